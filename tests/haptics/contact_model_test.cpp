// The force a device feels: zero out of contact, pushing out and growing with depth,
// resisting the cut's advance, never above the limit nor jumping between samples.

#include "incise/haptics/contact_model.hpp"

#include <gtest/gtest.h>

#include <thread>

#include "incise/haptics/haptic_loop.hpp"
#include "incise/mesh/boundary.hpp"
#include "incise/mesh/generators.hpp"

namespace incise {
namespace {

/// A 4 x 6 x 4 cm block (the default scene's) and its boundary.
struct Block {
  TetMesh mesh;
  std::vector<Triangle> triangles;
  std::vector<std::uint8_t> on_cut;
  Block() : mesh(make_box_grid({{4, 6, 4}, Vec3(0.04, 0.06, 0.04), Vec3::Zero(), 6})) {
    for (const BoundaryFace& face : boundary_faces(mesh)) {
      triangles.push_back(face.vertices);
    }
    on_cut.assign(triangles.size(), 0);
  }
  [[nodiscard]] ContactModel model(const BladePose& blade, const HapticSpec& spec = {}) const {
    return build_contact_model(triangles, on_cut, mesh.rest_positions(), blade, Material{}, spec);
  }
};

/// A vertical blade 5 cm long whose tip is at `tip`.
BladePose vertical_blade(const Vec3& tip) {
  return {0.0, tip, tip + Vec3(0, 0, 0.05)};
}

TEST(ContactModel, FindsTheTopFaceWhereTheBladeEnters) {
  const Block block;
  const ContactModel model = block.model(vertical_blade(Vec3(0.021, 0.03, 0.03)));
  ASSERT_TRUE(model.has_surface);
  EXPECT_NEAR(model.anchor.z(), 0.04, 1e-12);
  EXPECT_NEAR(model.normal.dot(Vec3::UnitZ()), 1.0, 1e-12);
  EXPECT_GT(model.stiffness, 0.0);
  EXPECT_LE(model.stiffness, HapticSpec{}.contact_stiffness_limit);
  // The touched triangle and the anchor's place in it: where the tissue feels the reaction.
  ASSERT_LT(model.triangle, block.triangles.size());
  Vec3 at = Vec3::Zero();
  double sum = 0.0;
  for (std::size_t k = 0; k < 3; ++k) {
    EXPECT_GE(model.barycentric[k], 0.0);
    sum += model.barycentric[k];
    at += model.barycentric[k] * block.mesh.rest_position(block.triangles[model.triangle][k]);
  }
  EXPECT_NEAR(sum, 1.0, 1e-12);
  EXPECT_LT((at - model.anchor).norm(), 1e-12);
}

TEST(ContactModel, NearestSurfacePointInsideOnAnEdgeAndAtACorner) {
  const std::vector<Vec3> points{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(5, 5, 5)};
  const std::vector<Triangle> triangles{{0, 1, 2}, {1, 3, 2}};
  const std::vector<std::uint8_t> exterior{0, 1};  // the second is a cut face: never touched
  const auto at = [&](const Vec3& p) {
    return nearest_surface_point(triangles, exterior, points, p);
  };
  const SurfacePoint above = at(Vec3(0.25, 0.25, 3.0));
  EXPECT_EQ(above.triangle, 0u);
  EXPECT_NEAR(above.barycentric[1], 0.25, 1e-12);
  EXPECT_NEAR(above.barycentric[2], 0.25, 1e-12);
  const SurfacePoint beside = at(Vec3(0.5, -2.0, 0.0));  // nearest the edge 0-1
  EXPECT_NEAR(beside.barycentric[0], 0.5, 1e-12);
  EXPECT_NEAR(beside.barycentric[1], 0.5, 1e-12);
  EXPECT_NEAR(beside.barycentric[2], 0.0, 1e-12);
  const SurfacePoint corner = at(Vec3(3.0, 3.0, 0.0));  // nearer the cut face: still triangle 0
  EXPECT_EQ(corner.triangle, 0u);
  EXPECT_NEAR(corner.barycentric[0], 0.0, 1e-12);
  EXPECT_NEAR(corner.barycentric[1] + corner.barycentric[2], 1.0, 1e-12);
  EXPECT_EQ(nearest_surface_point({}, {}, points, Vec3::Zero()).triangle,
            static_cast<std::size_t>(-1));
}

TEST(ContactModel, ZeroOutOfContact) {
  const Block block;
  const BladePose above = vertical_blade(Vec3(0.021, 0.03, 0.045));
  const ContactModel model = block.model(above);
  const ForceSample sample = evaluate_force(model, above, Vec3(0, 0.05, 0));
  EXPECT_EQ(sample.total(), Vec3::Zero());
  EXPECT_EQ(sample.depth, 0.0);
  // Beside the body, below its top: the side face is the one touched, and the tip is outside.
  const BladePose beside = vertical_blade(Vec3(-0.01, 0.03, 0.01));
  EXPECT_EQ(evaluate_force(block.model(beside), beside, Vec3::Zero()).total(), Vec3::Zero());
}

TEST(ContactModel, PushesOutAndGrowsWithDepth) {
  const Block block;
  const ContactModel model = block.model(vertical_blade(Vec3(0.021, 0.03, 0.039)));
  double previous = 0.0;
  for (double depth = 0.001; depth <= 0.02; depth += 0.001) {
    const BladePose pose = vertical_blade(Vec3(0.021, 0.03, 0.04 - depth));
    const ForceSample sample = evaluate_force(model, pose, Vec3::Zero());
    EXPECT_NEAR(sample.depth, depth, 1e-12);
    EXPECT_GT(sample.contact.dot(model.normal), previous) << depth;  // grows, pushes out
    EXPECT_NEAR(sample.contact.norm(), model.stiffness * depth, 1e-9);
    previous = sample.contact.dot(model.normal);
  }
}

TEST(ContactModel, ResistsTheCutInProportionToItsAdvance) {
  HapticSpec spec;
  spec.cutting_toughness = 200.0;
  const Block block;
  const BladePose pose = vertical_blade(Vec3(0.021, 0.03, 0.02));  // 2 cm in the tissue
  const ContactModel model = block.model(pose, spec);
  EXPECT_EQ(evaluate_force(model, pose, Vec3::Zero()).cutting, Vec3::Zero());
  const Vec3 slow(0, 0.2 * spec.advance_speed, 0);
  const ForceSample at_slow = evaluate_force(model, pose, slow);
  const ForceSample at_twice = evaluate_force(model, pose, 2.0 * slow);
  EXPECT_NEAR(at_slow.wetted_length, 0.02, 1e-12);
  EXPECT_LT(at_slow.cutting.dot(slow), 0.0);                                  // against the motion
  EXPECT_NEAR(at_twice.cutting.norm(), 2.0 * at_slow.cutting.norm(), 1e-12);  // proportional
  // Fast: the work of cutting, toughness x wetted length per metre of advance.
  const ForceSample fast = evaluate_force(model, pose, Vec3(0, 0.1, 0));
  EXPECT_NEAR(fast.cutting.norm(), 200.0 * 0.02, 1e-9);
  // Sliding along its own axis cuts nothing.
  EXPECT_EQ(evaluate_force(model, pose, Vec3(0, 0, -0.05)).cutting, Vec3::Zero());
  // Deeper in the tissue, more blade is wetted: more resistance.
  const BladePose deeper = vertical_blade(Vec3(0.021, 0.03, 0.01));
  EXPECT_GT(evaluate_force(model, deeper, Vec3(0, 0.1, 0)).cutting.norm(), fast.cutting.norm());
}

TEST(ContactModel, CutFacesAreNotTheSurfaceTheBladePresses) {
  Block block;
  std::fill(block.on_cut.begin(), block.on_cut.end(), 1);
  const BladePose pose = vertical_blade(Vec3(0.021, 0.03, 0.03));
  EXPECT_FALSE(block.model(pose).has_surface);
  EXPECT_EQ(evaluate_force(block.model(pose), pose, Vec3(0, 1, 0)).total(), Vec3::Zero());
}

TEST(ContactModel, FadesOutFarFromWhereItWasBuilt) {
  // A wide slab (20 x 20 x 4 cm): around its middle the touched region is its top alone.
  TetMesh slab = make_box_grid({{10, 10, 2}, Vec3(0.2, 0.2, 0.04), Vec3::Zero(), 6});
  std::vector<Triangle> triangles;
  for (const BoundaryFace& face : boundary_faces(slab)) {
    triangles.push_back(face.vertices);
  }
  const std::vector<std::uint8_t> on_cut(triangles.size(), 0);
  const auto model_at = [&](const BladePose& blade) {
    return build_contact_model(triangles, on_cut, slab.rest_positions(), blade, Material{}, {});
  };
  const Vec3 centre(0.1, 0.1, 0.03);
  const ContactModel model = model_at(vertical_blade(centre));
  ASSERT_NEAR(model.normal.z(), 1.0, 1e-12);
  const double full = evaluate_force(model, vertical_blade(centre), Vec3::Zero()).contact.norm();
  EXPECT_NEAR(full, model.stiffness * 0.01, 1e-12);
  const Vec3 along(0.6, 0.8, 0.0);
  double previous = full;
  for (double offset = 0.0; offset <= 2.5 * model.radius; offset += model.radius / 50.0) {
    const double now =
        evaluate_force(model, vertical_blade(centre + offset * along), Vec3::Zero()).contact.norm();
    EXPECT_LE(now, previous + 1e-12) << offset;                // fades, never grows
    EXPECT_LE(previous - now, full / 50.0 + 1e-12) << offset;  // continuously
    if (offset < model.radius) {
      EXPECT_NEAR(now, full, 1e-12);
    }
    if (offset > 2.0 * model.radius) {
      EXPECT_EQ(now, 0.0);
    }
    previous = now;
  }
}

TEST(ForceFilter, ClampsAndLimitsEveryStep) {
  ForceFilter filter(3.0, 0.05);
  Vec3 previous = Vec3::Zero();
  // A force that jumps about wildly, NaN included.
  const std::vector<Vec3> wanted = {Vec3(10, 0, 0),           Vec3(-10, 5, 0), Vec3(0, 0, 0),
                                    Vec3(std::nan(""), 0, 0), Vec3(0, 0, 2),   Vec3(1, 1, 1)};
  for (int repeat = 0; repeat < 200; ++repeat) {
    for (const Vec3& force : wanted) {
      const Vec3 sent = filter.apply(force);
      EXPECT_TRUE(sent.allFinite());
      EXPECT_LE(sent.norm(), 3.0 + 1e-12);
      EXPECT_LE((sent - previous).norm(), 0.05 + 1e-12);
      previous = sent;
    }
  }
  // Held long enough, it reaches what is wanted (within the limit).
  for (int i = 0; i < 200; ++i) {
    filter.apply(Vec3(0, 0, 2));
  }
  EXPECT_NEAR((filter.last() - Vec3(0, 0, 2)).norm(), 0.0, 1e-12);
}

TEST(VelocityEstimator, AveragesOverItsWindow) {
  VelocityEstimator estimator(0.01);
  for (int i = 0; i <= 50; ++i) {
    const double t = 1.0 + i * 0.001;
    estimator.add(t, Vec3(0.1 * t, 0, 0) + Vec3(0, (i % 2) * 1e-6, 0));  // jitter in y
  }
  EXPECT_NEAR(estimator.velocity().x(), 0.1, 1e-9);
  EXPECT_LT(std::abs(estimator.velocity().y()), 2e-4);
  estimator.add(0.5, Vec3::Zero());  // the clock went back: start afresh
  EXPECT_EQ(estimator.velocity(), Vec3::Zero());
}

TEST(DurationHistogram, Quantiles) {
  DurationHistogram histogram;
  for (int i = 1; i <= 1000; ++i) {
    histogram.add(i * 1e-6);
  }
  EXPECT_NEAR(histogram.quantile(0.5), 500e-6, 1.5e-6);
  EXPECT_NEAR(histogram.quantile(0.99), 990e-6, 1.5e-6);
  EXPECT_DOUBLE_EQ(histogram.max(), 1000e-6);
  histogram.add(1.0);  // beyond the bins: still the max
  EXPECT_DOUBLE_EQ(histogram.max(), 1.0);
}

TEST(HapticLoop, AnswersEveryPoseWithAFilteredForce) {
  HapticSpec spec;
  spec.rate = 1000.0;
  std::mutex mutex;
  std::vector<Vec3> forces;
  HapticLoop loop(spec, [&](const Vec3& force, const DevicePose&) {
    const std::lock_guard lock(mutex);
    forces.push_back(force);
  });
  const Block block;
  const BladePose deep = vertical_blade(Vec3(0.021, 0.03, 0.02));
  loop.set_model(std::make_shared<const ContactModel>(block.model(deep)));
  loop.start();
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  {
    const std::lock_guard lock(mutex);
    EXPECT_TRUE(forces.empty());  // no pose yet: nothing is sent
  }
  DevicePose pose;
  pose.blade = deep;
  pose.received = std::chrono::steady_clock::now();
  loop.post_pose(pose);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  loop.stop();
  const HapticStatistics statistics = loop.statistics();
  const std::lock_guard lock(mutex);
  ASSERT_GT(forces.size(), 100u);
  Vec3 previous = Vec3::Zero();
  for (const Vec3& force : forces) {
    EXPECT_LE((force - previous).norm(), spec.max_force_step + 1e-12);
    EXPECT_LE(force.norm(), spec.force_limit + 1e-12);
    previous = force;
  }
  EXPECT_GT(forces.back().z(), 0.0);  // out of the tissue, upwards
  EXPECT_EQ(statistics.latencies, 1u);
  EXPECT_GT(statistics.ticks, 200u);
  EXPECT_GT(statistics.period_p50, 0.0);
}

}  // namespace
}  // namespace incise
