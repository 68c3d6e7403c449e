// The console's catalogue connections, held for its lifetime: opened on first use, then lent to one request at a time.
#pragma once
#include <condition_variable>
#include <cstddef>
#include <filesystem>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "stand/catalogue/catalogue.h"

namespace fpss::console {

// Read-only connections to the catalogue at `url` (serve --catalogue), or RUNS_DIR/stand.db when it
// is empty: at most `size` at once (a pool for PostgreSQL, where a connection costs a round trip
// and the server's slots; as many for SQLite, whose connections are not shared between threads).
// A connection is opened when first needed and kept; one whose use threw is closed, not returned
// (a server that restarted, a file that was replaced), and the next lease opens a new one.
class CataloguePool {
 public:
  CataloguePool(std::filesystem::path runs_dir, std::string url, size_t size = 4);
  CataloguePool(const CataloguePool&) = delete;
  CataloguePool& operator=(const CataloguePool&) = delete;

  // One connection for the holder's use; false when there is no catalogue yet (no SQLite file) or
  // it cannot be opened now (the server is away): the console shows no runs rather than failing.
  class Lease {
   public:
    Lease(Lease&& o) noexcept;
    Lease& operator=(Lease&&) = delete;
    ~Lease();
    explicit operator bool() const { return cat_ != nullptr; }
    Catalogue& operator*() const { return *cat_; }
    Catalogue* operator->() const { return cat_.get(); }

   private:
    friend class CataloguePool;
    Lease(CataloguePool* pool, std::unique_ptr<Catalogue> cat);
    CataloguePool* pool_;
    std::unique_ptr<Catalogue> cat_;
    int exceptions_ = 0;  // in flight when it was lent: more at its end means its use threw
  };
  // Waits while every connection is lent.
  Lease acquire();

  const std::filesystem::path& runs_dir() const { return runs_dir_; }
  // Connections opened so far, over the pool's life (the console's tests count them).
  size_t opened() const;

 private:
  void give_back(std::unique_ptr<Catalogue> cat, bool broken);
  std::unique_ptr<Catalogue> open();

  const std::filesystem::path runs_dir_;
  const std::string url_;
  const bool default_file_;  // url_ is RUNS_DIR/stand.db, which may not exist yet
  const size_t size_;
  mutable std::mutex m_;
  std::condition_variable free_;
  std::vector<std::unique_ptr<Catalogue>> idle_;
  size_t lent_ = 0;
  size_t opened_ = 0;
};

}  // namespace fpss::console
