#pragma once
// Where frames go: the engine hands each finished frame to its sinks (the .pvd/.vtu series,
// a recorder of the tool path; later a renderer, a network peer, a checkpoint writer).
// Sinks run on the thread that steps the engine; their time is the frame's rd stage.

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "incise/cut/blade.hpp"
#include "incise/io/mesh_io.hpp"

namespace incise {

class Engine;
struct FrameRecord;
struct ClippedElements;

/// Writes an XFEM body's elements clipped to their sides (xfem/clipped_elements.hpp) as a
/// .vtu with cell arrays `element` and `fraction`, and the frame's time (s) and the length
/// unit (m per coordinate unit) if given.
void write_clipped_vtu(const std::filesystem::path& path, const ClippedElements& clipped,
                       std::optional<double> time = std::nullopt,
                       std::optional<double> length_unit_m = std::nullopt);

/// What watches a running engine's frames (Engine::add_sink): a file series, a recorder, a
/// checkpoint writer. Called on the engine's thread.
class FrameSink {
 public:
  FrameSink() = default;
  FrameSink(const FrameSink&) = delete;
  FrameSink& operator=(const FrameSink&) = delete;
  virtual ~FrameSink() = default;

  /// The engine's state before its next frame (frame 0 for a new engine) when the sink is added.
  virtual void begin(const Engine& /*engine*/) {}
  /// After each frame that did not diverge. Returns whether it wrote output for this frame.
  virtual bool frame(const Engine& engine, const FrameRecord& record) = 0;
  /// The run ends (Engine::finish): the engine holds the last frame, or the last good one
  /// before a divergence.
  virtual void end(const Engine& /*engine*/) {}
};

/// A ParaView series: `DIR/NAME.pvd` and `DIR/NAME_NNNNNN.vtu` with current positions,
/// displacement (m) and velocity (m/s), every `every`-th frame, the first and the last. An XFEM
/// body's frames carry every element's material `fraction` from the first frame on, and a
/// second series, `NAME_clipped.pvd`, holds the elements clipped to their sides.
class VtuSeriesSink final : public FrameSink {
 public:
  /// `last_frame`: written even off the `every` grid (-1: unknown; end() writes it then).
  /// `continue_series`: a resumed run keeps the entries the .pvd already lists before its
  /// first frame, so both runs make one series.
  VtuSeriesSink(const std::filesystem::path& dir, std::string name, int every = 1,
                int last_frame = -1, bool continue_series = false);
  void begin(const Engine& engine) override;
  bool frame(const Engine& engine, const FrameRecord& record) override;
  void end(const Engine& engine) override;
  [[nodiscard]] const std::filesystem::path& pvd() const {
    return series_.path();
  }  ///< DIR/NAME.pvd
  /// The embedded visual surface's series (written only when the scene has one).
  [[nodiscard]] const std::filesystem::path& visual_pvd() const { return visual_series_.path(); }
  /// An XFEM body's virtual elements clipped to their sides (written only for XFEM scenes):
  /// what a reader that does not weigh by `fraction` should integrate.
  [[nodiscard]] const std::filesystem::path& clipped_pvd() const { return clipped_series_.path(); }

 private:
  void write(const Engine& engine);
  std::filesystem::path dir_;
  std::string name_;
  int every_;
  int last_frame_;
  int written_frame_ = -1;
  bool continue_series_;
  PvdSeries series_;
  PvdSeries visual_series_;   ///< NAME_visual.pvd, when the scene has a visual surface
  PvdSeries clipped_series_;  ///< NAME_clipped.pvd, when the scene cuts with XFEM
};

/// Records the blade pose of every frame to a blade-path CSV at the end, so a live session
/// (mouse, device) can be replayed with ScriptedToolPath::from_csv: the pose the cutter cut
/// with, in the rest frame (a live pose carried back from the world). Frames with the tool
/// lifted are left out (the CSV format has no gaps: a replay moves straight across them).
class ToolPathRecorder final : public FrameSink {
 public:
  /// The CSV is written at end().
  explicit ToolPathRecorder(std::filesystem::path csv);
  void begin(const Engine& engine) override;
  bool frame(const Engine& engine, const FrameRecord& record) override;
  void end(const Engine& engine) override;
  [[nodiscard]] const std::vector<BladePose>& poses() const { return poses_; }  ///< so far

 private:
  std::filesystem::path csv_;
  std::vector<BladePose> poses_;
};

}  // namespace incise
