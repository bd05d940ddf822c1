#pragma once
// A plan prepared once and predicted as often as the moves change: the seed's interactive
// planning (Teschner et al.: the bone cut and realigned, the face following). Preparing builds
// everything that does not depend on the moves (surfaces from the CT or the files, the bone's
// segments, the layered tissue balanced in its scanned state, soft-tissue cuts); a move is
// checked against the other segments and refused where they would interpenetrate; a prediction
// starts from the last one (warm), or from the scanned state (cold: what `incise plan` computes
// for the same moves, bit for bit). `incise plan` is one session with the plan's own moves.
//
// Threads: one at a time. A viewer keeps the session on its worker thread and reads copies.

#include <memory>
#include <nlohmann/json_fwd.hpp>
#include <span>
#include <utility>
#include <vector>

#include "incise/planning/plan.hpp"

namespace incise::planning {

/// A plan prepared once (image, surfaces, bone segments, tissue, equilibrium), then moved and
/// predicted as often as asked: what `incise plan --view` and Python's incise.PlanSession
/// drive. One thread at a time.
class PlanSession {
 public:
  /// Prepares the plan and sets its moves; throws InputError (naming the plan's key) for bad
  /// input and for moves whose segments interpenetrate, before the soft tissue is built.
  explicit PlanSession(const PlanDescription& plan, const PlanProgress& progress = {});
  ~PlanSession();
  PlanSession(const PlanSession&) = delete;
  PlanSession& operator=(const PlanSession&) = delete;

  /// The plan it was made from.
  [[nodiscard]] const PlanDescription& plan() const;
  [[nodiscard]] const SurfaceMesh& bone() const;  ///< m, the surface that was cut
  /// The bone's segments.
  [[nodiscard]] const BoneSegments& segments() const;
  /// The soft tissue.
  [[nodiscard]] const LayeredTissue& tissue() const;
  /// The segment of the bone triangle nearest `point` (m).
  [[nodiscard]] int segment_near(const Vec3& point) const;
  /// The mean of the segment's triangles' corners (m): where its rotations turn about.
  [[nodiscard]] Vec3 segment_centre(int segment) const;

  /// One move per segment (identity where it stays).
  [[nodiscard]] std::span<const RigidMove> moves() const;
  /// Replaces one segment's move unless the segments would then interpenetrate (beyond the
  /// plan's contact_tolerance): returns the pairs that would (empty: the move is made).
  std::vector<Interpenetration> try_move(int segment, const RigidMove& move);

  /// Predicts the soft tissue for the current moves: from the last prediction (warm), or from
  /// the scanned state. `progress` gets Newton's iterations.
  const MinimizeResult& predict(bool warm, const PlanProgress& progress = {});
  /// Factorises the tissue's Hessian where the last prediction left it, so that the next warm
  /// prediction (a nudge) starts from a factor of that minimum and needs no factorisation of
  /// its own (about one factorisation: 0.1-0.2 s on a 10k-point model, 2 cores). The planning
  /// viewer calls it after showing each prediction, while the user's hand moves to the next;
  /// called after every prediction, the predictions stay the same for the same moves, bit for
  /// bit. Nothing for the quasi-Newton methods. Throws InputError where the Hessian cannot be
  /// factorised (a free point held by no spring).
  void prepare_next_nudge();
  /// How the last prediction went.
  [[nodiscard]] const MinimizeResult& last_prediction() const;
  /// N: the largest force left on a free point after the last prediction.
  [[nodiscard]] double residual_force() const;
  /// Every point of the tissue, predicted (m); the scanned state before any prediction.
  [[nodiscard]] std::span<const Vec3> positions() const;
  /// The skin over the tissue's columns: triangles, scanned and predicted positions (m).
  [[nodiscard]] std::span<const Triangle> skin_triangles() const;
  /// The skin's scanned positions (m).
  [[nodiscard]] std::vector<Vec3> skin_before() const;
  /// The skin's predicted positions (m).
  [[nodiscard]] std::vector<Vec3> skin_after() const;

  /// The plan as JSON with the current moves in place of its own (each names a point of its
  /// segment in mm): saved, `incise plan` reproduces the cold prediction exactly.
  [[nodiscard]] nlohmann::json plan_with_moves(const nlohmann::json& original) const;

  /// What preparing found (report.json's keys) and how long each stage took (s).
  [[nodiscard]] const nlohmann::json& preparation_report() const;
  /// Seconds per preparation stage.
  [[nodiscard]] const nlohmann::json& preparation_seconds() const;
  /// The skin springs a soft-tissue cut removed (their ends: the gap opens between them).
  [[nodiscard]] std::span<const std::pair<int, int>> cut_skin_springs() const;
  /// N: the largest free force the predictions aim below.
  [[nodiscard]] double gradient_tolerance() const;

 private:
  struct State;
  static std::vector<char> free_points(const State& state);
  std::unique_ptr<State> state_;
};

/// Each Newton step of a prediction as report.json's `newton.steps` (and Python's
/// `predict()["steps"]`): lagged_iterations, lagged_budget, lagged, convexified, factorized,
/// step_length, gradient.
[[nodiscard]] nlohmann::json newton_steps_report(const std::vector<NewtonStep>& steps);

}  // namespace incise::planning
