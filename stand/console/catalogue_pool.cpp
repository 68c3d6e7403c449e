#include "stand/console/catalogue_pool.h"

#include <exception>
#include <utility>

namespace fpss::console {

namespace fs = std::filesystem;

CataloguePool::CataloguePool(fs::path runs_dir, std::string url, size_t size)
    : runs_dir_(std::move(runs_dir)),
      url_(url.empty() ? Catalogue::default_path(runs_dir_).string() : std::move(url)),
      default_file_(url.empty()),
      size_(size == 0 ? 1 : size) {}

CataloguePool::Lease::Lease(CataloguePool* pool, std::unique_ptr<Catalogue> cat)
    : pool_(pool), cat_(std::move(cat)), exceptions_(std::uncaught_exceptions()) {}

CataloguePool::Lease::Lease(Lease&& o) noexcept
    : pool_(std::exchange(o.pool_, nullptr)), cat_(std::move(o.cat_)), exceptions_(o.exceptions_) {}

CataloguePool::Lease::~Lease() {
  if (pool_) pool_->give_back(std::move(cat_), std::uncaught_exceptions() > exceptions_);
}

CataloguePool::Lease CataloguePool::acquire() {
  std::unique_lock<std::mutex> lock(m_);
  free_.wait(lock, [&] { return lent_ < size_; });
  ++lent_;
  if (!idle_.empty()) {
    auto cat = std::move(idle_.back());
    idle_.pop_back();
    return Lease(this, std::move(cat));
  }
  lock.unlock();
  // Opened outside the lock: a server that is slow to answer holds up only this request.
  std::unique_ptr<Catalogue> cat;
  try {
    cat = open();
  } catch (...) {
    give_back(nullptr, true);
    throw;
  }
  return Lease(this, std::move(cat));
}

std::unique_ptr<Catalogue> CataloguePool::open() {
  // A missing SQLite file is "no runs yet", not an error (read-only never creates one).
  if (default_file_ && !fs::exists(url_)) return nullptr;
  try {
    auto cat = open_catalogue(url_, Catalogue::Mode::read_only);
    std::lock_guard<std::mutex> lock(m_);
    ++opened_;
    return cat;
  } catch (const std::exception&) {
    return nullptr;
  }
}

void CataloguePool::give_back(std::unique_ptr<Catalogue> cat, bool broken) {
  {
    std::lock_guard<std::mutex> lock(m_);
    --lent_;
    if (cat && !broken) idle_.push_back(std::move(cat));
  }
  free_.notify_one();
}

size_t CataloguePool::opened() const {
  std::lock_guard<std::mutex> lock(m_);
  return opened_;
}

}  // namespace fpss::console
