#include "incise/view/session_recording.hpp"

#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "incise/core/error.hpp"

namespace incise {

namespace {

using Json = nlohmann::json;

Json pose_json(const BladePose& pose) {
  return Json::array({pose.time, pose.tip.x(), pose.tip.y(), pose.tip.z(), pose.base.x(),
                      pose.base.y(), pose.base.z()});
}

Json action_json(const SessionAction& action) {
  return Json{{"frame", action.frame}, {"action", action.name}, {"value", action.value}};
}

}  // namespace

SceneDescription SessionSegment::scene() const {
  return parse_scene(scene_text, scene_file);
}

void write_session(const std::filesystem::path& path, const SessionRecording& recording) {
  std::ostringstream out;
  out << Json{{"incise_session", 1}}.dump() << "\n";
  for (const SessionSegment& segment : recording.segments) {
    out << Json{{"frame", 0},
                {"start",
                 {{"scene_file", segment.scene_file.string()}, {"scene", segment.scene_text}}}}
               .dump()
        << "\n";
    // Poses and actions in frame order (actions of a frame after its pose).
    std::size_t next_action = 0;
    for (std::size_t frame = 0; frame < segment.poses.size(); ++frame) {
      const auto& pose = segment.poses[frame];
      Json row = pose ? Json{{"frame", frame}, {"pose", pose_json(*pose)}}
                      : Json{{"frame", frame}, {"lift", true}};
      const bool passed = frame < segment.passed.size() && !segment.passed[frame].empty();
      if ((pose || passed) && frame < segment.world.size() && segment.world[frame] != 0) {
        row["world"] = true;
      }
      if (passed) {
        Json through = Json::array();
        for (const auto& through_pose : segment.passed[frame]) {
          through.push_back(through_pose ? pose_json(*through_pose) : Json(nullptr));
        }
        row["through"] = std::move(through);
      }
      out << row.dump() << "\n";
      while (next_action < segment.actions.size() &&
             segment.actions[next_action].frame <= static_cast<int>(frame)) {
        out << action_json(segment.actions[next_action++]).dump() << "\n";
      }
    }
    for (; next_action < segment.actions.size(); ++next_action) {
      out << action_json(segment.actions[next_action]).dump() << "\n";
    }
  }
  write_file_atomically(path, out.str());
}

SessionRecording read_session(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) {
    throw InputError(path.string(), 0, "cannot open the session recording");
  }
  SessionRecording recording;
  std::string text;
  std::size_t line = 0;
  const auto fail = [&](const std::string& message) {
    throw InputError(path.string(), line, message);
  };
  const auto blade_pose = [&](const Json& p, const char* key) {
    if (!p.is_array() || p.size() != 7 ||
        !std::all_of(p.begin(), p.end(), [](const Json& v) { return v.is_number(); })) {
      fail(std::string("\"") + key +
           "\" must hold 7 numbers [t, tip_x, tip_y, tip_z, base_x, base_y, base_z]");
    }
    return BladePose{p[0].get<double>(),
                     Vec3(p[1].get<double>(), p[2].get<double>(), p[3].get<double>()),
                     Vec3(p[4].get<double>(), p[5].get<double>(), p[6].get<double>())};
  };
  while (std::getline(in, text)) {
    ++line;
    if (text.empty()) {
      continue;
    }
    Json row;
    try {
      row = Json::parse(text);
    } catch (const Json::exception& error) {
      fail(std::string("not JSON: ") + error.what());
    }
    if (line == 1) {
      if (!row.is_object() || !row.contains("incise_session")) {
        fail("not an incise session recording (no {\"incise_session\": 1} header)");
      }
      if (row["incise_session"] != 1) {
        fail("a session recording of a newer version");
      }
      continue;
    }
    if (!row.is_object() || !row.contains("frame") || !row["frame"].is_number_integer() ||
        row["frame"].get<long long>() < 0) {
      fail("each line needs \"frame\": a frame number");
    }
    const int frame = row["frame"].get<int>();
    if (row.contains("start")) {
      const Json& start = row["start"];
      if (!start.is_object() || !start.contains("scene") || !start["scene"].is_string()) {
        fail("\"start\" needs \"scene\": the scene's JSON text");
      }
      SessionSegment segment;
      segment.scene_file = start.value("scene_file", std::string());
      segment.scene_text = start["scene"].get<std::string>();
      recording.segments.push_back(std::move(segment));
      continue;
    }
    if (recording.segments.empty()) {
      fail("a frame before any \"start\"");
    }
    SessionSegment& segment = recording.segments.back();
    if (row.contains("action")) {
      if (!row["action"].is_string()) {
        fail("\"action\" must be a name");
      }
      segment.actions.push_back(
          {frame, row["action"].get<std::string>(), row.value("value", std::string())});
      continue;
    }
    if (frame != static_cast<int>(segment.poses.size())) {
      fail("pose of frame " + std::to_string(frame) + " where frame " +
           std::to_string(segment.poses.size()) + " was expected");
    }
    if (row.contains("world") && !row["world"].is_boolean()) {
      fail("\"world\" must be true or false");
    }
    segment.world.push_back(row.value("world", false) ? 1 : 0);
    if (row.contains("lift")) {
      segment.poses.emplace_back();
    } else if (row.contains("pose")) {
      segment.poses.push_back(blade_pose(row["pose"], "pose"));
    } else {
      fail("a line needs \"start\", \"pose\", \"lift\" or \"action\"");
    }
    if (row.contains("through")) {
      const Json& through = row["through"];
      if (!through.is_array()) {
        fail("\"through\" must be a list of poses and nulls");
      }
      segment.passed.resize(segment.poses.size());
      for (const Json& passed : through) {
        segment.passed.back().push_back(
            passed.is_null() ? std::nullopt
                             : std::optional<BladePose>(blade_pose(passed, "through")));
      }
    }
  }
  if (line == 0) {
    throw InputError(path.string(), 0, "empty session recording");
  }
  if (recording.segments.empty() || recording.segments.back().poses.empty()) {
    throw InputError(path.string(), line, "the recording has no frames");
  }
  return recording;
}

void SessionRecorder::begin(const Engine& engine) {
  SessionSegment segment;
  segment.scene_file = engine.scene().file;
  segment.scene_text = engine.scene().source_text;
  segment.poses.push_back(engine.blade());
  segment.world.push_back(engine.blade_frame() == PoseFrame::kWorld ? 1 : 0);
  recording_->segments.push_back(std::move(segment));
}

bool SessionRecorder::frame(const Engine& engine, const FrameRecord& record) {
  auto& poses = recording_->segments.back().poses;
  INCISE_ASSERT(record.frame == static_cast<int>(poses.size()), "frames recorded out of order");
  poses.push_back(engine.blade());
  SessionSegment& segment = recording_->segments.back();
  segment.world.push_back(engine.blade_frame() == PoseFrame::kWorld ? 1 : 0);
  if (!engine.blade_passed().empty()) {
    segment.passed.resize(poses.size());
    segment.passed.back() = engine.blade_passed();
  }
  return false;
}

void SessionRecorder::action(int frame, std::string name, std::string value) {
  INCISE_ASSERT(!recording_->segments.empty(), "an action before the session started");
  recording_->segments.back().actions.push_back({frame, std::move(name), std::move(value)});
}

std::optional<BladePose> RecordedToolPoses::pose(int frame, double /*time*/) {
  if (frame < 0 || static_cast<std::size_t>(frame) >= poses_.size()) {
    return std::nullopt;
  }
  const auto at = static_cast<std::size_t>(frame);
  frame_ = at < world_.size() && world_[at] != 0 ? PoseFrame::kWorld : PoseFrame::kRest;
  return poses_[at];
}

ToolMotion RecordedToolPoses::motion(int frame, double time) {
  ToolMotion motion{{}, pose(frame, time)};
  if (frame >= 0 && static_cast<std::size_t>(frame) < passed_.size()) {
    motion.passed = passed_[static_cast<std::size_t>(frame)];
  }
  return motion;
}

SceneDescription viewer_scene(SceneDescription scene) {
  if (scene.tool.cutter == CutterKind::kNone) {
    scene.tool.cutter = CutterKind::kSubdivision;  // the viewer's scalpel cuts any scene
  }
  return scene;
}

std::unique_ptr<Engine> replay_engine(const SessionSegment& segment) {
  auto engine = std::make_unique<Engine>(viewer_scene(segment.scene()));
  engine->set_tool_source(
      std::make_unique<RecordedToolPoses>(segment.poses, segment.world, segment.passed));
  return engine;
}

}  // namespace incise
