#pragma once
// The one way incise runs a loop in parallel: body(first, last) over pieces of [begin, end),
// each piece at most a few `grain`s long, the pieces on any threads in any order. A body
// may write only what its own indices own; sums that must not depend on the thread count
// are taken over fixed chunks by the caller (see linear_solvers.cpp).
//
// oneTBB runs the pieces. Under ThreadSanitizer they run on plain threads instead, three of
// them taking the pieces in turn: Debian's libtbb is not instrumented, so TSan cannot see the
// order its scheduler puts between the caller and its workers and would report every loop as
// a race. Threads it sees created and joined give it that order exactly, so what it still
// reports is a body touching memory another piece touches: the races these loops must not
// have. Include only from .cpp files of modules that link TBB::tbb.

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

#include <algorithm>
#include <cstddef>

#if defined(__SANITIZE_THREAD__)
#define INCISE_THREAD_SANITIZER 1
#elif defined(__has_feature)
#if __has_feature(thread_sanitizer)
#define INCISE_THREAD_SANITIZER 1
#endif
#endif

#ifdef INCISE_THREAD_SANITIZER
#include <exception>
#include <thread>
#include <vector>
#endif

namespace incise {

template <typename Body>
void parallel_for(std::size_t begin, std::size_t end, std::size_t grain, const Body& body) {
  if (begin >= end) {
    return;
  }
  grain = std::max<std::size_t>(grain, 1);
#ifdef INCISE_THREAD_SANITIZER
  constexpr std::size_t kThreads = 3;
  const std::size_t pieces = (end - begin + grain - 1) / grain;
  std::vector<std::exception_ptr> failures(kThreads);
  std::vector<std::thread> threads;
  for (std::size_t t = 0; t < std::min(kThreads, pieces); ++t) {
    threads.emplace_back([&, t] {
      try {
        for (std::size_t piece = t; piece < pieces; piece += kThreads) {
          const std::size_t first = begin + piece * grain;
          body(first, std::min(end, first + grain));
        }
      } catch (...) {
        failures[t] = std::current_exception();
      }
    });
  }
  for (std::thread& thread : threads) {
    thread.join();
  }
  for (const std::exception_ptr& failure : failures) {
    if (failure) {
      std::rethrow_exception(failure);
    }
  }
#else
  tbb::parallel_for(
      tbb::blocked_range<std::size_t>(begin, end, grain),
      [&](const tbb::blocked_range<std::size_t>& range) { body(range.begin(), range.end()); });
#endif
}

/// Runs first() and second() at once (each may use parallel_for inside). They must not write
/// what the other reads or writes. Under ThreadSanitizer, second() runs on a plain thread.
template <typename First, typename Second>
void parallel_invoke(const First& first, const Second& second) {
#ifdef INCISE_THREAD_SANITIZER
  std::exception_ptr failure;
  std::thread thread([&] {
    try {
      second();
    } catch (...) {
      failure = std::current_exception();
    }
  });
  try {
    first();
  } catch (...) {
    thread.join();
    throw;
  }
  thread.join();
  if (failure) {
    std::rethrow_exception(failure);
  }
#else
  tbb::parallel_invoke(first, second);
#endif
}

}  // namespace incise
