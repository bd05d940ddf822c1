#pragma once
// Blade paths that exercise a cutter: a straight sweep across a body, and a seeded random
// walk with what hands do (reversals, tremor, stops, lifting out and re-entering, curves, a
// tilting blade). Used by the tests, `incise soak` and the benchmarks.

#include <random>
#include <vector>

#include "incise/cut/blade.hpp"

namespace incise {

/// A vertical blade (from `margin` of the z-extent below the box to as far above it) swept
/// along x at `y_fraction` of the y-extent, from `margin` of the x-extent before the box to
/// `end_fraction` of its x-extent, in `poses` moves `dt` s apart (m, s).
[[nodiscard]] std::vector<BladePose> sweep_along_x(const Vec3& low, const Vec3& high,
                                                   double y_fraction, double end_fraction,
                                                   int poses, double margin = 0.1,
                                                   double dt = 0.01);

/// `poses` poses 0.01 s apart of a random walk over the box [low, high] (m), drawn from
/// `rng`: the blade spans the box's height and wanders in x and y, sometimes beyond the box.
[[nodiscard]] std::vector<BladePose> random_blade_walk(const Vec3& low, const Vec3& high,
                                                       std::mt19937& rng, int poses);

}  // namespace incise
