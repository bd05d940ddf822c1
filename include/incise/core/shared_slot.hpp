#pragma once
// A value one thread publishes and others take: a shared_ptr to an immutable object, swapped
// under a lock held only to copy the pointer, so a reader waits at most for a pointer copy,
// never for the writer's work, and an old value is destroyed outside the lock.
//
// Not std::atomic<std::shared_ptr>: libstdc++ 12 (Debian 12's) releases its lock after a load
// with a relaxed store, so the pointer the load read is not ordered before a later store's
// write. That is a data race by the memory model, and ThreadSanitizer reports it
// (google/sanitizers#1558); a mutex orders both, visibly.

#include <memory>
#include <mutex>
#include <utility>

namespace incise {

/// One shared_ptr handed from thread to thread under a mutex held only for a pointer copy
/// (libstdc++ 12's std::atomic<std::shared_ptr> orders its load wrongly; see the file's top).
template <typename T>
class SharedSlot {
 public:
  /// Any thread: `value` replaces what was there.
  void store(std::shared_ptr<T> value) {
    {
      const std::lock_guard lock(mutex_);
      value_.swap(value);
    }
    // `value` now holds the old one: released here, outside the lock.
  }
  /// Any thread: the newest value (null before the first store).
  [[nodiscard]] std::shared_ptr<T> load() const {
    const std::lock_guard lock(mutex_);
    return value_;
  }

 private:
  mutable std::mutex mutex_;
  std::shared_ptr<T> value_;
};

}  // namespace incise
