#include "incise/core/child_process.hpp"

#include <poll.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iostream>

// Sanitizers reserve terabytes of address space for their shadow memory: an address-space
// limit would stop them, not the allocation it is meant for.
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define INCISE_SANITIZED_BUILD 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer) || \
    __has_feature(memory_sanitizer)
#define INCISE_SANITIZED_BUILD 1
#endif
#endif

namespace incise {
namespace {

/// Limits the calling process's address space to what it uses now plus `budget` bytes.
void limit_address_space(std::size_t budget) {
  std::size_t pages = 0;
  std::ifstream statm("/proc/self/statm");
  if (!(statm >> pages)) {
    return;  // no /proc: leave the process unlimited rather than guess
  }
  const auto now = static_cast<rlim_t>(pages) * static_cast<rlim_t>(::sysconf(_SC_PAGESIZE));
  rlimit limit{};
  if (::getrlimit(RLIMIT_AS, &limit) != 0) {
    return;
  }
  const rlim_t wanted = now + static_cast<rlim_t>(budget);
  if (limit.rlim_max == RLIM_INFINITY || wanted < limit.rlim_max) {
    limit.rlim_cur = wanted;
    (void)::setrlimit(RLIMIT_AS, &limit);
  }
}

}  // namespace

bool child_memory_budget_applies() {
#ifdef INCISE_SANITIZED_BUILD
  return false;
#else
  return true;
#endif
}

bool write_all(int fd, const void* bytes, std::size_t size) {
  const auto* data = static_cast<const char*>(bytes);
  while (size > 0) {
    const ssize_t written = ::write(fd, data, size);
    if (written <= 0) {
      if (written < 0 && errno == EINTR) {
        continue;
      }
      return false;
    }
    data += written;
    size -= static_cast<std::size_t>(written);
  }
  return true;
}

ChildOutcome run_in_child(const std::function<void(int fd)>& work, double timeout_seconds,
                          std::size_t memory_budget) {
  ChildOutcome outcome;
  int fds[2];
  if (::pipe(fds) != 0) {
    outcome.start_error = std::string("cannot create a pipe: ") + std::strerror(errno);
    return outcome;
  }
  std::cout.flush();  // else what is buffered would be written twice
  std::cerr.flush();
  const pid_t child = ::fork();
  if (child < 0) {
    outcome.start_error = std::string("cannot fork: ") + std::strerror(errno);
    ::close(fds[0]);
    ::close(fds[1]);
    return outcome;
  }
  if (child == 0) {
    ::close(fds[0]);
    if (memory_budget > 0 && child_memory_budget_applies()) {
      limit_address_space(memory_budget);
    }
    try {
      work(fds[1]);
    } catch (...) {
      std::_Exit(1);
    }
    std::_Exit(0);  // no destructors or exit handlers of the parent's state in the child
  }
  ::close(fds[1]);
  const auto deadline =
      std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_seconds);
  char buffer[1 << 16];
  for (;;) {
    const double left =
        std::chrono::duration<double>(deadline - std::chrono::steady_clock::now()).count();
    if (left <= 0.0) {
      ::kill(child, SIGKILL);
      outcome.timed_out = true;
      break;
    }
    pollfd poll_fd{fds[0], POLLIN, 0};
    const int ready = ::poll(&poll_fd, 1, static_cast<int>(std::min(left * 1000.0, 1000.0)) + 1);
    if (ready < 0 && errno != EINTR) {
      ::kill(child, SIGKILL);
      break;
    }
    if (ready <= 0) {
      continue;
    }
    const ssize_t got = ::read(fds[0], buffer, sizeof(buffer));
    if (got < 0 && errno == EINTR) {
      continue;
    }
    if (got <= 0) {
      break;  // end of data: the child closed its end or ended
    }
    outcome.output.append(buffer, static_cast<std::size_t>(got));
  }
  ::close(fds[0]);
  int status = 0;
  while (::waitpid(child, &status, 0) < 0 && errno == EINTR) {
  }
  if (WIFSIGNALED(status)) {
    outcome.signal = WTERMSIG(status);
  } else if (WIFEXITED(status)) {
    outcome.exit_code = WEXITSTATUS(status);
  }
  return outcome;
}

}  // namespace incise
