#include "plan_worker.hpp"

#include <fmt/format.h>

#include <Eigen/Geometry>
#include <chrono>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <utility>

#include "incise/core/atomic_file.hpp"
#include "incise/core/error.hpp"
#include "incise/core/timing.hpp"

namespace incise::app {

namespace {

using planning::kMillimetre;
constexpr double kDegree = 3.14159265358979323846 / 180.0;
/// A nudge into contact is cut in half this many times, looking for the part that fits.
constexpr int kContactHalvings = 5;

}  // namespace

PlanWorker::PlanWorker(planning::PlanDescription plan, std::string plan_text,
                       std::function<void()> on_change)
    : plan_(std::move(plan)),
      plan_text_(std::move(plan_text)),
      on_change_(std::move(on_change)),
      thread_([this] { loop(); }) {}

PlanWorker::~PlanWorker() {
  {
    const std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  thread_.join();
}

void PlanWorker::request(PlanRequest request) {
  {
    const std::lock_guard lock(mutex_);
    requests_.push_back(std::move(request));
    running_ = true;
  }
  wake_.notify_all();
}

PlanState PlanWorker::state() const {
  const std::lock_guard lock(mutex_);
  return state_;
}

bool PlanWorker::idle() const {
  const std::lock_guard lock(mutex_);
  return !running_ && requests_.empty();
}

void PlanWorker::publish(const std::function<void(PlanState&)>& change) {
  {
    const std::lock_guard lock(mutex_);
    change(state_);
    ++state_.revision;
  }
  if (on_change_) {
    on_change_();
  }
}

void PlanWorker::prepare(const planning::PlanDescription& plan) {
  auto session = std::make_unique<planning::PlanSession>(
      plan, [this](const std::string& stage, double fraction) {
        publish([&](PlanState& s) {
          s.status = fmt::format("preparing ({:.0f} %): {}", 100.0 * fraction, stage);
        });
      });
  session_ = std::move(session);
  const planning::BoneSegments& segments = session_->segments();
  centres_.clear();
  for (int segment = 0; segment < segments.count; ++segment) {
    centres_.push_back(session_->segment_centre(segment));
  }
  // The plan's own moves are where a session starts, as poses about the segments' centres:
  // R (x - c) + c + t = R (x - s) + s + t' with t' = t + c - s + R (s - c).
  poses_.assign(static_cast<std::size_t>(segments.count), SegmentPose{});
  for (std::size_t s = 0; s < poses_.size(); ++s) {
    const planning::RigidMove& move = session_->moves()[s];
    if (move.angle == 0.0 && move.translation == Vec3::Zero()) {
      continue;
    }
    const Mat3 rotation = Eigen::AngleAxisd(move.angle, move.axis.normalized()).toRotationMatrix();
    poses_[s].rotation = rotation;
    poses_[s].translation_mm =
        (move.translation + move.center - centres_[s] + rotation * (centres_[s] - move.center)) /
        kMillimetre;
  }
  publish([&](PlanState& s) {
    s.skin_triangles.assign(session_->skin_triangles().begin(), session_->skin_triangles().end());
    s.skin_before = session_->skin_before();
    s.bone_segment.assign(segments.triangle_segment.begin(), segments.triangle_segment.end());
    s.segment_volumes_mm3.clear();
    for (const double v : segments.volumes) {
      s.segment_volumes_mm3.push_back(v / std::pow(kMillimetre, 3));
    }
    s.poses = poses_;
    s.segment_centres = centres_;
    s.osteotomies = static_cast<int>(plan.osteotomies.size());
    s.status = "predicting...";
  });
}

void PlanWorker::loop() {
  try {
    prepare(plan_);
    predict();
  } catch (const std::exception& error) {
    publish([&](PlanState& s) {
      s.error = error.what();
      s.status = std::string("error: ") + error.what();
      s.busy = false;
    });
    const std::lock_guard lock(mutex_);
    running_ = false;
    return;
  }
  finish_request();
  for (;;) {
    PlanRequest next;
    {
      std::unique_lock lock(mutex_);
      running_ = !requests_.empty();
      state_.busy = running_;
      wake_.wait(lock, [this] { return stopping_ || !requests_.empty(); });
      if (stopping_) {
        return;
      }
      next = std::move(requests_.front());
      requests_.pop_front();
      running_ = true;
      state_.busy = true;
    }
    try {
      if (next.kind == PlanRequest::Kind::kNudge) {
        nudge(next);
      } else if (next.kind == PlanRequest::Kind::kCut) {
        cut(next);
      } else {
        save(next.path);
      }
    } catch (const std::exception& error) {
      publish([&](PlanState& s) { s.status = std::string("error: ") + error.what(); });
    }
    finish_request();
  }
}

void PlanWorker::finish_request() {
  {
    const std::lock_guard lock(mutex_);
    running_ = !requests_.empty();
    state_.busy = running_;
  }
  if (on_change_) {
    on_change_();
  }
  if (!prepare_next_) {
    return;
  }
  // While the face is looked at and the hand moves to the next nudge (not busy: the window
  // takes the next drag meanwhile, and its request waits for this): a factor of this minimum,
  // so that the next prediction needs none of its own. After every prediction, not only when
  // no request waits, so that the same requests give the same predictions, bit for bit.
  prepare_next_ = false;
  try {
    session_->prepare_next_nudge();
  } catch (const std::exception& error) {
    publish([&](PlanState& s) { s.status = std::string("error: ") + error.what(); });
  }
}

void PlanWorker::nudge(const PlanRequest& request) {
  const planning::BoneSegments& segments = session_->segments();
  if (request.segment < 0 || request.segment >= segments.count) {
    publish([&](PlanState& s) { s.status = fmt::format("no segment {}", request.segment); });
    return;
  }
  const auto index = static_cast<std::size_t>(request.segment);
  const SegmentPose before = poses_[index];
  // The largest part of the nudge that keeps the segments apart: all of it, else halves.
  double fraction = 1.0;
  std::vector<planning::Interpenetration> contact;
  for (int halving = 0; halving <= kContactHalvings; ++halving, fraction *= 0.5) {
    SegmentPose pose = before;
    pose.translation_mm += fraction * request.translate_mm;
    const Vec3 turn = fraction * request.rotate_deg * kDegree;
    if (turn.norm() > 0.0) {
      pose.rotation =
          Eigen::AngleAxisd(turn.norm(), turn.normalized()).toRotationMatrix() * pose.rotation;
    }
    planning::RigidMove move;
    const Eigen::AngleAxisd rotation(pose.rotation);
    move.axis = rotation.axis();
    move.angle = rotation.angle();
    move.center = centres_[index];
    move.translation = pose.translation_mm * kMillimetre;
    move.segment_near = centres_[index];
    contact = session_->try_move(request.segment, move);
    if (contact.empty()) {
      poses_[index] = pose;
      break;
    }
  }
  if (!contact.empty()) {
    publish([&](PlanState& s) {
      s.status =
          fmt::format("segment {} stays: the nudge would push it into segment {}", request.segment,
                      contact.front().first == request.segment ? contact.front().second
                                                               : contact.front().first);
    });
    return;
  }
  publish([&](PlanState& s) {
    s.poses = poses_;
    s.status = fraction < 1.0 ? fmt::format(
                                    "predicting... (segment {} stopped at contact, "
                                    "{:.0f} % of the nudge)",
                                    request.segment, 100.0 * fraction)
                              : "predicting...";
  });
  predict();
}

void PlanWorker::cut(const PlanRequest& request) {
  if (!(request.normal.norm() > 0.0) || !request.point_mm.allFinite() ||
      !request.normal.allFinite()) {
    publish([&](PlanState& s) { s.status = "no cut: the plane needs a point and a normal"; });
    return;
  }
  // The plan as it stands (its moves included), with one more plane: parsed as any plan is, so
  // that Save writes it and incise plan runs it.
  nlohmann::json plan = session_->plan_with_moves(nlohmann::json::parse(plan_text_));
  if (!plan.contains("osteotomies")) {
    plan["osteotomies"] = nlohmann::json::array();
  }
  const Vec3 normal = request.normal.normalized();
  plan["osteotomies"].push_back(
      {{"point", {request.point_mm.x(), request.point_mm.y(), request.point_mm.z()}},
       {"normal", {normal.x(), normal.y(), normal.z()}}});
  std::string text = plan.dump(2) + "\n";
  planning::PlanDescription description = planning::parse_plan(text, plan_.file);
  try {
    prepare(description);
  } catch (const std::exception& error) {
    // The session before the cut stays (prepare replaces it only once the new one is made).
    publish([&](PlanState& s) { s.status = std::string("no cut: ") + error.what(); });
    return;
  }
  plan_ = std::move(description);
  plan_text_ = std::move(text);
  predict();
}

void PlanWorker::predict() {
  const auto start = Clock::now();
  const planning::MinimizeResult& result = session_->predict(/*warm=*/true);
  const double seconds = seconds_since(start);
  std::vector<Vec3> skin_after = session_->skin_after();
  const std::vector<std::array<Vec3, 3>> moved =
      planning::moved_triangles(session_->bone(), session_->segments(), session_->moves());
  publish([&](PlanState& s) {
    s.skin_after = std::move(skin_after);
    s.largest_displacement_mm = 0.0;
    for (std::size_t i = 0; i < s.skin_after.size(); ++i) {
      s.largest_displacement_mm =
          std::max(s.largest_displacement_mm, (s.skin_after[i] - s.skin_before[i]).norm() * 1e3);
    }
    s.bone_corners.clear();
    for (const auto& corners : moved) {
      s.bone_corners.insert(s.bone_corners.end(), corners.begin(), corners.end());
    }
    ++s.predictions;
    s.ready = true;
    s.status = fmt::format("predicted in {:.2f} s ({} Newton steps{}), largest {:.2f} mm", seconds,
                           result.iterations, result.converged ? "" : ", NOT converged",
                           s.largest_displacement_mm);
    // A line per prediction on the console, from this thread so that every one is there in
    // order: the session's log, and what a script driving the window waits for.
    std::cout << fmt::format("prediction {}: largest skin displacement {:.6f} mm\n", s.predictions,
                             s.largest_displacement_mm)
              << std::flush;
  });
  prepare_next_ = true;
}

void PlanWorker::save(const std::filesystem::path& path) {
  const nlohmann::json saved = session_->plan_with_moves(nlohmann::json::parse(plan_text_));
  write_file_atomically(path, saved.dump(2) + "\n");
  publish([&](PlanState& s) { s.status = "saved " + path.string(); });
}

}  // namespace incise::app
