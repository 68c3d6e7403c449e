// The SQLite backend of the catalogue: one file per stand, the embedded default (RUNS_DIR/stand.db).
#pragma once
#include <filesystem>
#include <memory>

#include "stand/catalogue/sql_catalogue.h"

namespace SQLite {
class Database;
}

namespace fpss {

// Safe for several processes at once (WAL, busy timeout, short IMMEDIATE transactions) and for a
// process killed at any point (SQLite's journal).
class SqliteCatalogue final : public SqlCatalogue {
 public:
  // read_write creates the file (and its folder) and the schema when missing; read_only throws
  // InputError when the file is missing or not a catalogue. Both throw InputError for a schema
  // newer than this software knows.
  explicit SqliteCatalogue(const std::filesystem::path& path, Mode mode = Mode::read_write,
                           int busy_timeout_ms = 10000);
  ~SqliteCatalogue() override;
  SqliteCatalogue(const SqliteCatalogue&) = delete;
  SqliteCatalogue& operator=(const SqliteCatalogue&) = delete;

  const std::filesystem::path& path() const { return path_; }
  std::string location() const override { return path_.string(); }
  std::string backend() const override { return "sqlite"; }

  std::string integrity_check() const override;
  int schema_version() const override;

  // The connection, for tests; prefer the methods above.
  SQLite::Database& database() { return *db_; }

 private:
  void transact(const std::string& what, const std::function<void(SqlSession&)>& body) override;
  void query(const std::string& what, const std::function<void(SqlSession&)>& body) const override;
  void init_schema();
  std::filesystem::path path_;
  std::unique_ptr<SQLite::Database> db_;
};

}  // namespace fpss
