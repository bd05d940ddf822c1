#pragma once
// What the hand feels: the force model a 1 kHz haptic loop evaluates between physics frames.
// The physics refreshes it once per frame (build_contact_model), linearised around the state
// of that frame: the tissue surface the blade touches as a plane with a contact stiffness,
// and the work it costs to cut there. Evaluating it is a few dozen flops, so the device loop
// never waits for the physics (the seed's Fig. 1: the device in its own process, the
// simulation feeding it).

#include <array>
#include <cstdint>
#include <span>

#include "incise/cut/blade.hpp"
#include "incise/physics/material.hpp"
#include "incise/scene/scene.hpp"

namespace incise {

/// The tissue around the blade, frozen for one physics frame.
struct ContactModel {
  bool has_surface = false;     ///< false: no body near the blade (the force is zero)
  Vec3 anchor = Vec3::Zero();   ///< m, where the blade enters the surface (or nearest)
  Vec3 normal = Vec3::UnitZ();  ///< outward unit normal of the touched region
  double radius = 0.0;          ///< m: the plane holds within it and fades out by 2x
  double stiffness = 0.0;       ///< N/m, against penetration
  double toughness = 0.0;       ///< J/m^2, work per area of cut
  double advance_speed = 0.01;  ///< m/s, where the cutting resistance saturates
  int frame = -1;               ///< the physics frame it was built from
  /// The touched triangle (index into the surface it was built from; none without contact)
  /// and the anchor's barycentric coordinates in it: where the tissue feels the reaction.
  std::size_t triangle = static_cast<std::size_t>(-1);
  std::array<double, 3> barycentric{1.0 / 3, 1.0 / 3, 1.0 / 3};  ///< the anchor in `triangle`
};

/// A point of a surface: its triangle and barycentric coordinates there.
struct SurfacePoint {
  std::size_t triangle = static_cast<std::size_t>(-1);           ///< none for an empty surface
  std::array<double, 3> barycentric{1.0 / 3, 1.0 / 3, 1.0 / 3};  ///< the point in `triangle`
};

/// The point of the exterior triangles (on_cut 0) nearest `point` (m): where a force at
/// `point` reaches a surface that was rebuilt since, or where a blade that enters no exterior
/// face touches. The first nearest triangle wins ties.
[[nodiscard]] SurfacePoint nearest_surface_point(std::span<const Triangle> triangles,
                                                 std::span<const std::uint8_t> on_cut,
                                                 std::span<const Vec3> positions,
                                                 const Vec3& point);

/// The force for one blade pose, in parts (N), and what it was computed from.
struct ForceSample {
  Vec3 contact = Vec3::Zero();  ///< pushes out along the normal, k * depth
  Vec3 cutting = Vec3::Zero();  ///< opposes the blade's advance in tissue
  double depth = 0.0;           ///< m of the tip below the surface (0 out of contact)
  double wetted_length = 0.0;   ///< m of blade below the surface
  /// The whole force (N).
  [[nodiscard]] Vec3 total() const { return contact + cutting; }
};

/// The contact model for a blade at `blade` against a boundary surface (triangles outward,
/// `on_cut` marks faces a cut opened: they are not the surface a blade presses on) of a body
/// of `material`. Pure: a function of positions, surface and parameters.
[[nodiscard]] ContactModel build_contact_model(std::span<const Triangle> triangles,
                                               std::span<const std::uint8_t> on_cut,
                                               std::span<const Vec3> positions,
                                               const BladePose& blade, const Material& material,
                                               const HapticSpec& haptics, int frame = -1);

/// The force on the blade at `pose` moving at `tip_velocity` (m/s). Zero without contact;
/// contact grows linearly with the tip's depth below the surface and pushes out along its
/// normal; cutting resistance is toughness x wetted length (the work per metre of advance),
/// against the blade's motion across its axis, growing linearly up to `advance_speed`.
[[nodiscard]] ForceSample evaluate_force(const ContactModel& model, const BladePose& pose,
                                         const Vec3& tip_velocity);

/// What reaches the device: magnitude clamped to `limit` (N), and no sample more than
/// `max_step` (N) from the previous one, so a new physics frame never kicks the hand.
class ForceFilter {
 public:
  /// `limit` and `max_step` in N.
  ForceFilter(double limit, double max_step);
  /// The force to send for `wanted` (N), clamped and rate-limited.
  Vec3 apply(const Vec3& wanted);
  /// Forgets the last force: the next one starts from zero.
  void reset() { last_ = Vec3::Zero(); }
  /// The last force sent (N).
  [[nodiscard]] const Vec3& last() const { return last_; }

 private:
  double limit_;
  double max_step_;
  Vec3 last_ = Vec3::Zero();
};

/// The tip's velocity from a stream of timed poses (s, m), averaged over `window` (s) so the
/// jitter of a 1 kHz stream does not become force noise.
class VelocityEstimator {
 public:
  /// Averages over `window` (s).
  explicit VelocityEstimator(double window = 0.01);
  /// A pose's time (s) and tip (m).
  void add(double time, const Vec3& tip);
  [[nodiscard]] Vec3 velocity() const;  ///< m/s
  /// Forgets every sample.
  void reset();

 private:
  struct Sample {
    double time = 0.0;
    Vec3 tip = Vec3::Zero();
  };
  double window_;
  std::array<Sample, 64> ring_{};  ///< the newest samples, oldest overwritten
  std::size_t count_ = 0;
  std::size_t next_ = 0;
};

}  // namespace incise
