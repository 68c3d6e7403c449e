// The SQLite backend of the catalogue: one file, WAL, short IMMEDIATE transactions.
#include "stand/catalogue/sqlite_catalogue.h"

#include <fmt/format.h>
#include <signal.h>
#include <unistd.h>

#include <SQLiteCpp/SQLiteCpp.h>
#include <sqlite3.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <ctime>
#include <functional>
#include <stdexcept>
#include <thread>
#include <type_traits>
#include <variant>

#include "base/errors.h"
#include "calib/coefficients.h"
#include "stand/catalogue/schema.h"

namespace fpss {
namespace {

namespace fs = std::filesystem;

[[noreturn]] void fail(const fs::path& path, const std::string& what, const SQLite::Exception& e) {
  // SQLITE_NOTADB (26) and SQLITE_CORRUPT (11) are about the file the user named.
  const int code = e.getErrorCode();
  if (code == SQLITE_NOTADB || code == SQLITE_CORRUPT || code == SQLITE_CANTOPEN) {
    throw InputError(fmt::format("{}: {}: {}", path.string(), what, e.what()));
  }
  throw std::runtime_error(fmt::format("{}: {}: {}", path.string(), what, e.what()));
}

// Runs `body` in a BEGIN IMMEDIATE transaction: the write lock is taken up front, so the busy
// timeout applies (a deferred transaction upgrading to a writer gets SQLITE_BUSY at once).
template <typename F>
void write_txn(SQLite::Database& db, F&& body) {
  SQLite::Transaction txn(db, SQLite::TransactionBehavior::IMMEDIATE);
  body();
  txn.commit();
}

// Runs `body`; an SQLite error becomes fail()'s, naming the file and what was being done.
template <typename F>
void guarded(const fs::path& path, const std::string& what, F&& body) {
  try {
    body();
  } catch (const SQLite::Exception& e) {
    fail(path, what, e);
  }
}

// A statement's current row, read by column name.
struct SqliteRow final : SqlRow {
  explicit SqliteRow(SQLite::Statement& s) : st(s) {}
  SQLite::Statement& st;

  SQLite::Column col(const std::string& c) const { return st.getColumn(c.c_str()); }
  std::string text(const std::string& c) const override { return col(c).getString(); }
  int64_t integer(const std::string& c) const override { return col(c).getInt64(); }
  bool flag(const std::string& c) const override { return col(c).getInt() != 0; }
  std::optional<std::string> opt_text(const std::string& c) const override {
    if (col(c).isNull()) return std::nullopt;
    return text(c);
  }
  std::optional<int64_t> opt_integer(const std::string& c) const override {
    if (col(c).isNull()) return std::nullopt;
    return integer(c);
  }
  std::optional<double> opt_real(const std::string& c) const override {
    if (col(c).isNull()) return std::nullopt;
    return col(c).getDouble();
  }
};

// Statements on the connection, inside whatever transaction the caller holds.
class SqliteSession final : public SqlSession {
 public:
  explicit SqliteSession(SQLite::Database& db) : db_(db) {}

  int64_t exec(const std::string& sql, const std::vector<SqlValue>& params) override {
    SQLite::Statement st(db_, sql);
    bind(st, params);
    return st.exec();
  }
  int64_t insert(const std::string& sql, const std::vector<SqlValue>& params) override {
    exec(sql, params);
    return db_.getLastInsertRowid();
  }
  void select(const std::string& sql, const std::vector<SqlValue>& params,
              const std::function<void(const SqlRow&)>& each) override {
    SQLite::Statement st(db_, sql);
    bind(st, params);
    const SqliteRow row(st);
    while (st.executeStep()) each(row);
  }

 private:
  // Bound by position; a boolean is stored as 0 or 1, SQLite's only booleans.
  static void bind(SQLite::Statement& st, const std::vector<SqlValue>& params) {
    for (size_t i = 0; i < params.size(); ++i) {
      const int k = static_cast<int>(i) + 1;
      std::visit(
          [&](const auto& v) {
            using T = std::decay_t<decltype(v)>;
            if constexpr (std::is_same_v<T, std::nullptr_t>) st.bind(k);
            else if constexpr (std::is_same_v<T, bool>) st.bind(k, v ? 1 : 0);
            else st.bind(k, v);
          },
          params[i]);
    }
  }

  SQLite::Database& db_;
};

}  // namespace

SqliteCatalogue::SqliteCatalogue(const fs::path& path, Mode mode, int busy_timeout_ms)
    : SqlCatalogue(schema::Dialect::sqlite), path_(path) {
  const bool ro = mode == Mode::read_only;
  if (ro && !fs::exists(path_)) {
    throw InputError(fmt::format("{}: no catalogue there (no run has been recorded with it)", path_.string()));
  }
  if (!ro && path_.has_parent_path()) fs::create_directories(path_.parent_path());
  try {
    db_ = std::make_unique<SQLite::Database>(
        path_, ro ? SQLite::OPEN_READONLY : (SQLite::OPEN_READWRITE | SQLite::OPEN_CREATE), busy_timeout_ms);
    db_->exec("PRAGMA foreign_keys = ON");
    if (!ro) {
      // Switching to WAL takes an exclusive lock that the busy handler does not always wait for
      // when another process is creating the file at the same moment: retry within the timeout.
      const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(busy_timeout_ms);
      for (;;) {
        try {
          const std::string jm = db_->execAndGet("PRAGMA journal_mode = WAL").getString();
          if (jm != "wal") throw std::runtime_error(fmt::format("{}: journal mode stays \"{}\"", path_.string(), jm));
          break;
        } catch (const SQLite::Exception& e) {
          if ((e.getErrorCode() & 0xff) != SQLITE_BUSY && (e.getErrorCode() & 0xff) != SQLITE_LOCKED) throw;
          if (std::chrono::steady_clock::now() > deadline) throw;
          std::this_thread::sleep_for(std::chrono::milliseconds(5));
        }
      }
      // FULL: a committed catalogue row survives a power cut too, not only a killed process.
      db_->exec("PRAGMA synchronous = FULL");
      init_schema();
    } else {
      const int v = schema_version();
      if (v == 0) {
        throw InputError(fmt::format("{}: not a stand catalogue (no schema)", path_.string()));
      }
      if (v > kSchemaVersion) {
        throw InputError(fmt::format("{}: catalogue schema version {} is newer than this fpss-stand ({})",
                                     path_.string(), v, kSchemaVersion));
      }
      if (v != kSchemaVersion) {
        // Migrations apply on first use, a read included: upgrade through a writer, then read.
        try {
          SqliteCatalogue upgrade(path_, Mode::read_write, busy_timeout_ms);
        } catch (const std::exception& e) {
          throw InputError(fmt::format("{}: catalogue schema version {} must be upgraded to {} and cannot be: {}",
                                       path_.string(), v, kSchemaVersion, e.what()));
        }
      }
    }
  } catch (const SQLite::Exception& e) {
    fail(path_, "cannot open the catalogue", e);
  }
}

SqliteCatalogue::~SqliteCatalogue() = default;

int SqliteCatalogue::schema_version() const { return db_->execAndGet("PRAGMA user_version").getInt(); }

// The missing migrations run inside the IMMEDIATE transaction that also sets user_version, so two
// processes opening a fresh file at once cannot both create it, and a crash leaves the version
// before or after.
void SqliteCatalogue::init_schema() {
  if (schema_version() == kSchemaVersion) return;  // the common case: no write lock needed
  write_txn(*db_, [&] {
    const int v = schema_version();  // again, under the lock: another process may have done it
    if (v > kSchemaVersion) {
      throw InputError(fmt::format("{}: catalogue schema version {} is newer than this fpss-stand ({})",
                                   path_.string(), v, kSchemaVersion));
    }
    for (int step = v; step < kSchemaVersion; ++step) db_->exec(schema::migration(step, schema::Dialect::sqlite));
    db_->exec(fmt::format("PRAGMA user_version = {}", kSchemaVersion));
  });
}

void SqliteCatalogue::transact(const std::string& what, const std::function<void(SqlSession&)>& body) {
  guarded(path_, "cannot " + what, [&] {
    write_txn(*db_, [&] {
      SqliteSession s(*db_);
      body(s);
    });
  });
}

void SqliteCatalogue::query(const std::string& what, const std::function<void(SqlSession&)>& body) const {
  guarded(path_, "cannot " + what, [&] {
    SqliteSession s(*db_);
    body(s);
  });
}

std::string SqliteCatalogue::integrity_check() const {
  try {
    std::string out;
    SQLite::Statement st(*db_, "PRAGMA integrity_check");
    while (st.executeStep()) {
      if (!out.empty()) out += "\n";
      out += st.getColumn(0).getString();
    }
    return out;
  } catch (const SQLite::Exception& e) {
    return fmt::format("integrity_check failed: {}", e.what());
  }
}

}  // namespace fpss
