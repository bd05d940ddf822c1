#pragma once
// Work done in a forked child process, for third-party code that can take the process down
// with it: TetGen double-frees after its own errors, Debian's GDCM aborts on assert(). The
// child writes its answer to a pipe; a crash, an abort or a hang becomes something the
// parent can report, and incise goes on. POSIX only.

#include <cstddef>
#include <functional>
#include <string>

namespace incise {

/// How a child process of run_in_child ended, and what it wrote.
struct ChildOutcome {
  std::string output;       ///< every byte the child wrote to its descriptor
  std::string start_error;  ///< non-empty: no child was started (pipe or fork failed)
  bool timed_out = false;   ///< killed after the time limit
  int signal = 0;           ///< the signal that ended the child; 0 if it exited
  int exit_code = 0;        ///< its exit status, when it exited
  /// Started, not timed out, not signalled, exit status 0.
  [[nodiscard]] bool exited_cleanly() const {
    return start_error.empty() && !timed_out && signal == 0 && exit_code == 0;
  }
};

/// Forks; the child runs work(fd), writing its answer to fd, and exits with status 0 when
/// work returns (work may _exit itself with another status). The parent reads everything the
/// child writes until it ends, killing it after `timeout_seconds`. The child must not return
/// into the caller's state: no exceptions escape work (they end the child with status 1).
/// `memory_budget` (bytes, 0: none) bounds what the child may add to the address space it
/// inherits (RLIMIT_AS): an allocation beyond it fails in the child (std::bad_alloc) instead
/// of taking the machine's memory. Not applied in sanitizer builds, whose shadow memory needs
/// terabytes of address space (child_memory_budget_applies() says which).
[[nodiscard]] ChildOutcome run_in_child(const std::function<void(int fd)>& work,
                                        double timeout_seconds, std::size_t memory_budget = 0);

/// Whether run_in_child's memory budget is applied in this build.
[[nodiscard]] bool child_memory_budget_applies();

/// Writes all of `bytes` to `fd`, retrying interrupted writes; false on any other failure.
bool write_all(int fd, const void* bytes, std::size_t size);

}  // namespace incise
