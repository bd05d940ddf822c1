#include "incise/physics/corotational_batch.hpp"

#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>

#include "incise/core/cpu_features.hpp"
#include "incise/core/error.hpp"

// The helpers below pass 32-byte vectors by value; the compilers warn that their ABI differs
// with and without AVX. They are internal to this file and always inlined, so no call
// crosses it.
#if defined(__clang__)
#pragma clang diagnostic ignored "-Wunknown-warning-option"
#endif
#if defined(__GNUC__)
#pragma GCC diagnostic ignored "-Wpsabi"
#endif

namespace incise {

namespace {

// GCC's and clang's vector extensions: one variable holds a quantity of the four lanes, and
// the compiler emits AVX2 for it inside functions built for AVX2 (two SSE2 halves elsewhere).
// Written this way, not with Eigen, because Eigen vectorises within one 3x3 matrix (which
// does not fill a register) and picks its SIMD width when compiled, not at run time.
using Lanes = double __attribute__((vector_size(4 * sizeof(double))));
using LaneMask = std::int64_t __attribute__((vector_size(4 * sizeof(double))));
static_assert(kElementLanes == 4, "the kernel is written for four lanes");

[[gnu::always_inline]] inline Lanes load(const double* source) {
  Lanes value;
  std::memcpy(&value, source, sizeof value);
  return value;
}

[[gnu::always_inline]] inline void store(double* target, const Lanes& value) {
  std::memcpy(target, &value, sizeof value);
}

[[gnu::always_inline]] inline Lanes broadcast(double value) {
  return Lanes{value, value, value, value};
}

/// mask ? a : b, lane by lane.
[[gnu::always_inline]] inline Lanes blend(const LaneMask& mask, const Lanes& a, const Lanes& b) {
  return std::bit_cast<Lanes>((std::bit_cast<LaneMask>(a) & mask) |
                              (std::bit_cast<LaneMask>(b) & ~mask));
}

[[gnu::always_inline]] inline bool any(const LaneMask& mask) {
  return (mask[0] | mask[1] | mask[2] | mask[3]) != 0;
}

[[gnu::always_inline]] inline Lanes square_root(const Lanes& value) {
  return Lanes{std::sqrt(value[0]), std::sqrt(value[1]), std::sqrt(value[2]), std::sqrt(value[3])};
}

/// A 3x3 matrix of each lane, column-major.
struct LaneMatrix {
  Lanes m[9];
  [[gnu::always_inline]] Lanes& operator()(int i, int j) { return m[3 * j + i]; }
  [[gnu::always_inline]] const Lanes& operator()(int i, int j) const { return m[3 * j + i]; }
};

/// The rotation of a unit quaternion (Eigen's toRotationMatrix, lane by lane).
[[gnu::always_inline]] inline LaneMatrix rotation_of(const Lanes q[4]) {
  const Lanes tx = q[1] + q[1];
  const Lanes ty = q[2] + q[2];
  const Lanes tz = q[3] + q[3];
  const Lanes twx = tx * q[0];
  const Lanes twy = ty * q[0];
  const Lanes twz = tz * q[0];
  const Lanes txx = tx * q[1];
  const Lanes txy = ty * q[1];
  const Lanes txz = tz * q[1];
  const Lanes tyy = ty * q[2];
  const Lanes tyz = tz * q[2];
  const Lanes tzz = tz * q[3];
  const Lanes one = broadcast(1.0);
  LaneMatrix r;
  r(0, 0) = one - (tyy + tzz);
  r(0, 1) = txy - twz;
  r(0, 2) = txz + twy;
  r(1, 0) = txy + twz;
  r(1, 1) = one - (txx + tzz);
  r(1, 2) = tyz - twx;
  r(2, 0) = txz - twy;
  r(2, 1) = tyz + twx;
  r(2, 2) = one - (txx + tyy);
  return r;
}

/// Copies lane 0's inputs into lanes count..3, so that every lane computes on defined numbers.
void fill_unused_lanes(CorotatedBatch& batch, int count) {
  for (int lane = count; lane < kElementLanes; ++lane) {
    for (int a = 0; a < 4; ++a) {
      for (int c = 0; c < 3; ++c) {
        batch.corners[a][c][lane] = batch.corners[a][c][0];
        batch.gradients[a][c][lane] = batch.gradients[a][c][0];
      }
      batch.quaternion[a][lane] = batch.quaternion[a][0];
    }
    batch.mu[lane] = batch.mu[0];
    batch.lambda[lane] = batch.lambda[0];
    batch.stress_scale[lane] = batch.stress_scale[0];
  }
}

/// Lanes whose rotation the vector iteration did not settle: polar_rotation() finishes them
/// from where the iteration left their warm start.
void finish_rotations_one_by_one(CorotatedBatch& batch, const LaneMask& unsettled, int count) {
  for (int lane = 0; lane < count; ++lane) {
    if (unsettled[lane] == 0) {
      continue;
    }
    Eigen::Quaterniond start = lane_quaternion(batch, lane);
    set_lane_matrix(batch.rotation, lane,
                    polar_rotation(lane_matrix(batch.deformation, lane), start));
    set_lane_quaternion(batch, lane, start);
  }
}

/// The whole kernel; inlined into an AVX2 build and a portable one.
[[gnu::always_inline]] inline void batch_kernel(CorotatedBatch& batch, int count) {
  // F = sum_a x_a (grad N_a)^T.
  LaneMatrix F;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      Lanes sum = load(batch.corners[0][i]) * load(batch.gradients[0][j]);
      for (int a = 1; a < 4; ++a) {
        sum += load(batch.corners[a][i]) * load(batch.gradients[a][j]);
      }
      F(i, j) = sum;
    }
  }
  Lanes squared_scale = broadcast(0.0);
  for (const Lanes& entry : F.m) {
    squared_scale += entry * entry;
  }
  // x - x is 0 only for finite x: a lane with a non-finite F goes to polar_rotation().
  const LaneMask finite = (squared_scale - squared_scale) == broadcast(0.0);
  const Lanes scale = square_root(blend(finite, squared_scale, broadcast(0.0)));
  const Lanes determinant_floor = 1e-6 * scale * scale * scale;
  const Lanes settled_turn = 1e-14 * (1.0 + scale);
  const Lanes squared_settled_turn = settled_turn * settled_turn;

  // polar_rotation()'s Newton step on skew(R^T F) = 0, in every lane still active: see there.
  Lanes q[4] = {load(batch.quaternion[0]), load(batch.quaternion[1]), load(batch.quaternion[2]),
                load(batch.quaternion[3])};
  const LaneMask in_use = LaneMask{0, 1, 2, 3} < LaneMask{count, count, count, count};
  LaneMask active = finite & in_use;
  LaneMask unsettled = ~finite & in_use;
  // Warm starts settle in one or two steps; what needs more goes one by one.
  constexpr int kVectorIterations = 4;
  for (int iteration = 0; iteration < kVectorIterations && any(active); ++iteration) {
    const LaneMatrix R = rotation_of(q);
    LaneMatrix local;  // R^T F
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) {
        local(i, j) = R(0, i) * F(0, j) + R(1, i) * F(1, j) + R(2, i) * F(2, j);
      }
    }
    const Lanes asymmetry[3] = {0.5 * (local(2, 1) - local(1, 2)),
                                0.5 * (local(0, 2) - local(2, 0)),
                                0.5 * (local(1, 0) - local(0, 1))};
    // G = tr(S) I - S with S = sym(R^T F).
    const Lanes trace = local(0, 0) + local(1, 1) + local(2, 2);
    const Lanes g00 = trace - local(0, 0);
    const Lanes g11 = trace - local(1, 1);
    const Lanes g22 = trace - local(2, 2);
    const Lanes g01 = -0.5 * (local(0, 1) + local(1, 0));
    const Lanes g02 = -0.5 * (local(0, 2) + local(2, 0));
    const Lanes g12 = -0.5 * (local(1, 2) + local(2, 1));
    const Lanes adj00 = g11 * g22 - g12 * g12;
    const Lanes adj01 = g02 * g12 - g01 * g22;
    const Lanes adj02 = g01 * g12 - g02 * g11;
    const Lanes adj11 = g00 * g22 - g02 * g02;
    const Lanes adj12 = g01 * g02 - g00 * g12;
    const Lanes adj22 = g00 * g11 - g01 * g01;
    const Lanes determinant = g00 * adj00 + g01 * adj01 + g02 * adj02;
    const LaneMask positive_definite =
        (g00 > 0.0) & (adj22 > 0.0) & (determinant > determinant_floor);
    const Lanes factor = 2.0 / blend(positive_definite, determinant, broadcast(1.0));
    const Lanes turn[3] = {
        factor * (adj00 * asymmetry[0] + adj01 * asymmetry[1] + adj02 * asymmetry[2]),
        factor * (adj01 * asymmetry[0] + adj11 * asymmetry[1] + adj12 * asymmetry[2]),
        factor * (adj02 * asymmetry[0] + adj12 * asymmetry[1] + adj22 * asymmetry[2])};
    const Lanes squared_angle = turn[0] * turn[0] + turn[1] * turn[1] + turn[2] * turn[2];
    const LaneMask newton = active & positive_definite;
    const LaneMask settled = newton & (squared_angle < squared_settled_turn);
    const LaneMask step = newton & ~settled & (squared_angle < 0.25);
    unsettled |= active & ~(settled | step);
    // q <- q (1, turn / 2), renormalised: R <- R exp(W) to first order, in the body frame.
    const Lanes hx = 0.5 * turn[0];
    const Lanes hy = 0.5 * turn[1];
    const Lanes hz = 0.5 * turn[2];
    Lanes next[4] = {
        q[0] - (q[1] * hx + q[2] * hy + q[3] * hz), q[0] * hx + q[1] + (q[2] * hz - q[3] * hy),
        q[0] * hy + q[2] + (q[3] * hx - q[1] * hz), q[0] * hz + q[3] + (q[1] * hy - q[2] * hx)};
    const Lanes inverse_norm = 1.0 / square_root(next[0] * next[0] + next[1] * next[1] +
                                                 next[2] * next[2] + next[3] * next[3]);
    for (int k = 0; k < 4; ++k) {
      q[k] = blend(step, next[k] * inverse_norm, q[k]);
    }
    // Quadratic convergence: after a turn below 1e-6 rad what is left is below 1e-12.
    active = step & ~(squared_angle < 1e-12);
  }
  unsettled |= active;

  const LaneMatrix rotation = rotation_of(q);
  for (int k = 0; k < 9; ++k) {
    store(batch.deformation[k], F.m[k]);
    store(batch.rotation[k], rotation.m[k]);
  }
  for (int k = 0; k < 4; ++k) {
    store(batch.quaternion[k], q[k]);
  }
  if (any(unsettled)) {
    finish_rotations_one_by_one(batch, unsettled, count);
  }

  // P = 2 mu (F - R) + lambda (tr(R^T F) - 3) R, scaled; and R grad N_a.
  LaneMatrix R;
  Lanes alignment = broadcast(0.0);
  for (int k = 0; k < 9; ++k) {
    R.m[k] = load(batch.rotation[k]);
    alignment += R.m[k] * F.m[k];
  }
  const Lanes scale_stress = load(batch.stress_scale);
  const Lanes shear = 2.0 * load(batch.mu) * scale_stress;
  const Lanes volumetric = load(batch.lambda) * (alignment - 3.0) * scale_stress;
  for (int k = 0; k < 9; ++k) {
    store(batch.scaled_stress[k], shear * (F.m[k] - R.m[k]) + volumetric * R.m[k]);
  }
  for (int a = 0; a < 4; ++a) {
    const Lanes g[3] = {load(batch.gradients[a][0]), load(batch.gradients[a][1]),
                        load(batch.gradients[a][2])};
    for (int i = 0; i < 3; ++i) {
      store(batch.rotated_gradients[a][i], R(i, 0) * g[0] + R(i, 1) * g[1] + R(i, 2) * g[2]);
    }
  }
}

/// Block entries k = 3 j + i in three parts: k = 0..3, k = 4..7 (a register each) and k = 8.
/// Entry (i, j) of lambda_a r^T + r mu_a^T is lambda_a[i] r[j] + r[i] mu_a[j], so each part
/// takes its row indices i and column indices j from the vectors by a fixed shuffle.
[[gnu::always_inline]] inline void warped_row_kernel(const std::array<Mat3*, 4>& blocks,
                                                     const Vec3& lambda_a, const Vec3& mu_a,
                                                     const std::array<Vec3, 4>& rotated,
                                                     const std::array<double, 4>& diagonal) {
  const Lanes lambda{lambda_a[0], lambda_a[1], lambda_a[2], lambda_a[0]};
  const Lanes mu{mu_a[0], mu_a[1], mu_a[2], mu_a[0]};
  // Parts 0 and 1: i = (0 1 2 0) and (1 2 0 1), j = (0 0 0 1) and (1 1 2 2).
  const Lanes lambda_i0 = lambda;
  const Lanes lambda_i1 = __builtin_shufflevector(lambda, lambda, 1, 2, 0, 1);
  const Lanes mu_j0 = __builtin_shufflevector(mu, mu, 0, 0, 0, 1);
  const Lanes mu_j1 = __builtin_shufflevector(mu, mu, 1, 1, 2, 2);
  const Lanes first_diagonal{1.0, 0.0, 0.0, 0.0};  // (0, 0) in part 0, (1, 1) in part 1
  for (int b = 0; b < 4; ++b) {
    const Vec3& r = rotated[static_cast<std::size_t>(b)];
    const Lanes r_lanes{r[0], r[1], r[2], r[0]};
    const Lanes r_i0 = r_lanes;
    const Lanes r_j0 = __builtin_shufflevector(r_lanes, r_lanes, 0, 0, 0, 1);
    const Lanes r_i1 = __builtin_shufflevector(r_lanes, r_lanes, 1, 2, 0, 1);
    const Lanes r_j1 = __builtin_shufflevector(r_lanes, r_lanes, 1, 1, 2, 2);
    const double d = diagonal[static_cast<std::size_t>(b)];
    double* entries = blocks[static_cast<std::size_t>(b)]->data();
    const Lanes d_lanes = d * first_diagonal;
    store(entries, load(entries) + lambda_i0 * r_j0 + r_i0 * mu_j0 + d_lanes);
    store(entries + 4, load(entries + 4) + lambda_i1 * r_j1 + r_i1 * mu_j1 + d_lanes);
    entries[8] += lambda_a[2] * r[2] + r[2] * mu_a[2] + d;
  }
}

void batch_portable(CorotatedBatch& batch, int count) {
  batch_kernel(batch, count);
}

void warped_row_portable(const std::array<Mat3*, 4>& blocks, const Vec3& lambda_a, const Vec3& mu_a,
                         const std::array<Vec3, 4>& rotated,
                         const std::array<double, 4>& diagonal) {
  warped_row_kernel(blocks, lambda_a, mu_a, rotated, diagonal);
}

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define INCISE_HAVE_AVX2_BATCH 1
__attribute__((target("avx2,fma"))) void batch_avx2(CorotatedBatch& batch, int count) {
  batch_kernel(batch, count);
}

__attribute__((target("avx2,fma"))) void warped_row_avx2(const std::array<Mat3*, 4>& blocks,
                                                         const Vec3& lambda_a, const Vec3& mu_a,
                                                         const std::array<Vec3, 4>& rotated,
                                                         const std::array<double, 4>& diagonal) {
  warped_row_kernel(blocks, lambda_a, mu_a, rotated, diagonal);
}

#endif

}  // namespace

void corotated_batch(CorotatedBatch& batch, int count) {
  INCISE_ASSERT(count >= 1 && count <= kElementLanes, "a batch holds 1 to 4 elements");
  fill_unused_lanes(batch, count);
#ifdef INCISE_HAVE_AVX2_BATCH
  if (cpu_has_avx2_fma()) {
    batch_avx2(batch, count);
    return;
  }
#endif
  batch_portable(batch, count);
}

void add_warped_stiffness_row(const std::array<Mat3*, 4>& blocks, const Vec3& lambda_a,
                              const Vec3& mu_a, const std::array<Vec3, 4>& rotated,
                              const std::array<double, 4>& diagonal) {
#ifdef INCISE_HAVE_AVX2_BATCH
  if (cpu_has_avx2_fma()) {
    warped_row_avx2(blocks, lambda_a, mu_a, rotated, diagonal);
    return;
  }
#endif
  warped_row_portable(blocks, lambda_a, mu_a, rotated, diagonal);
}

void detail::add_warped_stiffness_row_portable(const std::array<Mat3*, 4>& blocks,
                                               const Vec3& lambda_a, const Vec3& mu_a,
                                               const std::array<Vec3, 4>& rotated,
                                               const std::array<double, 4>& diagonal) {
  warped_row_portable(blocks, lambda_a, mu_a, rotated, diagonal);
}

void detail::corotated_batch_portable(CorotatedBatch& batch, int count) {
  INCISE_ASSERT(count >= 1 && count <= kElementLanes, "a batch holds 1 to 4 elements");
  fill_unused_lanes(batch, count);
  batch_portable(batch, count);
}

}  // namespace incise
