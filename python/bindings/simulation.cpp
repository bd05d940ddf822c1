// incise.Simulation: an Engine stepped from Python.
//
// Arrays that never go stale and never dangle: positions, velocities, rest positions and
// tetrahedra come out as read-only numpy arrays over a buffer the simulation mirrors from the
// engine at most once per frame (taking them again in the same frame copies nothing: the same
// memory). A buffer an array still holds is never written again: the next frame gets a fresh
// one, so an array keeps the values (and the length) of the frame it was taken in, across cuts
// that add vertices and restores alike. The engine's own vectors are never handed out, as a
// cut may move them.
//
// Thread rule: one engine, one owner. The GIL is released while the engine works (step,
// restore, render), and a mutex serialises every call that touches it, so a second Python
// thread runs meanwhile and a call from it on the same simulation waits its turn.

#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <mutex>

#include "arrays.hpp"
#include "bindings.hpp"
#include "incise/core/error.hpp"
#include "incise/engine/engine.hpp"
#include "incise/mesh/validate.hpp"
#include "incise/view/frame_scene.hpp"
#ifdef INCISE_HAVE_GL
#include "incise/render/offscreen.hpp"
#endif

namespace incise::python {

// Outside the anonymous namespace: Simulation holds four (g++ warns of a member whose type has
// internal linkage where the file is compiled as part of a unity build).
/// A copy of one engine array, refreshed when its stamp moves on; never rewritten while an
/// array outside holds it.
template <typename T>
class Mirror {
 public:
  [[nodiscard]] const std::shared_ptr<std::vector<T>>& of(std::span<const T> source,
                                                          std::uint64_t stamp) {
    if (!data_ || stamp != stamp_) {
      if (!data_ || data_.use_count() > 1) {
        data_ = std::make_shared<std::vector<T>>();
      }
      data_->assign(source.begin(), source.end());
      stamp_ = stamp;
    }
    return data_;
  }

 private:
  std::shared_ptr<std::vector<T>> data_;
  std::uint64_t stamp_ = 0;
};

namespace {

/// Holds the engine's mutex with the GIL released while waiting for it, so a thread stepping
/// without the GIL can finish and a waiting one cannot deadlock with it.
class EngineLock {
 public:
  explicit EngineLock(std::mutex& mutex) : lock_(mutex, std::defer_lock) {
    py::gil_scoped_release release;
    lock_.lock();
  }

 private:
  std::unique_lock<std::mutex> lock_;
};

PoseFrame pose_frame(const std::string& name) {
  if (name == "rest") {
    return PoseFrame::kRest;
  }
  if (name == "world") {
    return PoseFrame::kWorld;
  }
  throw InputError("frame: \"" + name + "\" is neither \"rest\" nor \"world\"");
}

SceneDescription scene_from(const py::object& scene,
                            const std::optional<std::filesystem::path>& file) {
  if (scene.is_none()) {
    return default_scene();
  }
  if (py::isinstance<py::dict>(scene)) {
    const std::string text = py::module_::import("json").attr("dumps")(scene).cast<std::string>();
    // Errors name `file`; relative paths resolve against its folder (the working folder when
    // none is given).
    return parse_scene(text, file.value_or("<scene dict>"));
  }
  if (py::isinstance<py::str>(scene) || py::hasattr(scene, "__fspath__")) {
    const auto path = scene.cast<std::filesystem::path>();
    py::gil_scoped_release release;
    return load_scene(path);
  }
  throw InputError("scene: a path, a dict or None (the default scene) is needed, not " +
                   std::string(py::str(scene.get_type())));
}

}  // namespace

class Simulation {
 public:
  explicit Simulation(std::unique_ptr<Engine> engine) : engine_(std::move(engine)) {}

  py::object step(std::optional<int> count) {
    const int frames = count.value_or(1);
    if (frames < 0) {
      throw InputError("step: the number of frames must be 0 or more, not " +
                       std::to_string(frames));
    }
    std::vector<FrameRecord> records;
    records.reserve(static_cast<std::size_t>(frames));
    std::string divergence;
    {
      py::gil_scoped_release release;
      const std::lock_guard lock(mutex_);
      if (engine_->diverged()) {
        divergence = engine_->divergence();
      }
      for (int k = 0; k < frames && divergence.empty(); ++k) {
        if (!engine_->step()) {
          divergence = engine_->divergence();
        } else {
          records.push_back(engine_->last_frame());
        }
      }
      ++stamp_;
    }
    if (!divergence.empty()) {
      PyErr_SetString(diverged_error().ptr(), divergence.c_str());
      throw py::error_already_set();
    }
    if (!count) {
      return py::cast(records.front());
    }
    return py::cast(records);
  }

  py::array positions() {
    const EngineLock lock(mutex_);
    return shared_points(positions_.of(engine_->positions(), stamp_));
  }
  py::array velocities() {
    const EngineLock lock(mutex_);
    return shared_points(velocities_.of(engine_->state().v.values(), stamp_));
  }
  py::array rest_positions() {
    const EngineLock lock(mutex_);
    return shared_points(rest_.of(engine_->mesh().rest_positions(), topology_stamp()));
  }
  py::array tets() {
    const EngineLock lock(mutex_);
    const auto& data = tets_.of(engine_->mesh().tets(), topology_stamp());
    return ids_view<4>(std::span<const Tet>(*data), keeper(data));
  }
  py::array labels() {
    const EngineLock lock(mutex_);
    const auto labels = engine_->mesh().tet_labels();
    return py::array_t<int>(static_cast<py::ssize_t>(labels.size()), labels.data());
  }
  std::shared_ptr<TetMesh> mesh() {
    const EngineLock lock(mutex_);
    return std::make_shared<TetMesh>(engine_->mesh());
  }

  void set_blade(const py::object& tip, const py::object& base, const std::string& frame) {
    const BladePose pose{0.0, point_from(tip, "tip"), point_from(base, "base")};
    if ((pose.tip - pose.base).norm() == 0.0) {
      throw InputError("set_blade: the tip and the base are the same point");
    }
    const PoseFrame wanted = pose_frame(frame);
    const EngineLock lock(mutex_);
    if (live_ == nullptr || live_->frame() != wanted) {
      auto source = std::make_unique<LiveToolPose>(wanted);
      live_ = source.get();
      engine_->set_tool_source(std::move(source));
    }
    live_->set(pose);
  }
  void lift_blade() {
    const EngineLock lock(mutex_);
    if (live_ != nullptr) {
      live_->lift();
    }
  }

  void push(std::size_t triangle, const py::object& barycentric, const py::object& force) {
    const Vec3 weights = point_from(barycentric, "barycentric");
    if (weights.minCoeff() < -1e-9 || std::abs(weights.sum() - 1.0) > 1e-6) {
      throw InputError("push: barycentric coordinates must be at least 0 and sum to 1");
    }
    const Vec3 newtons = point_from(force, "force");
    const EngineLock lock(mutex_);
    engine_->push(triangle, {weights.x(), weights.y(), weights.z()}, newtons);
  }

  py::bytes save_state() {
    std::string bytes;
    {
      const EngineLock lock(mutex_);
      py::gil_scoped_release release;
      bytes = engine_->save_state();
    }
    return py::bytes(bytes);
  }
  void restore(const py::bytes& state) {
    std::string bytes = state;  // copied under the GIL, restored without it
    const EngineLock lock(mutex_);
    py::gil_scoped_release release;
    replace(Engine::restore_state(bytes, "the state given to restore()"));
  }
  void checkpoint(const std::filesystem::path& path) {
    const EngineLock lock(mutex_);
    py::gil_scoped_release release;
    engine_->save_checkpoint(path);
  }

  py::array render(int width, int height, const std::string& mode_name) {
#ifdef INCISE_HAVE_GL
    const auto mode = parse_render_mode(mode_name);
    if (!mode) {
      throw InputError("render: mode \"" + mode_name + "\" is none of faces, wire, cut");
    }
    if (width < 1 || height < 1 || width > 8192 || height > 8192) {
      throw InputError("render: the size must be 1..8192 pixels a side");
    }
    Image image;
    {
      const EngineLock lock(mutex_);
      py::gil_scoped_release release;
      // Made once; any thread may use it, one at a time (the engine's lock is held).
      if (!renderer_) {
        renderer_ = std::make_unique<OffscreenRenderer>();
      }
      const FrameScene scene = frame_scene(*engine_);
      RenderOptions options;
      options.width = width;
      options.height = height;
      options.mode = *mode;
      const double aspect = static_cast<double>(width) / height;
      // The camera is fitted once per picture shape and kept, so pictures of later frames
      // compare (pixel observations see the body move, not the camera).
      if (!camera_ || camera_aspect_ != aspect) {
        camera_ = scene_camera(engine_->scene(), scene.bounds(), aspect);
        camera_aspect_ = aspect;
      }
      options.camera = *camera_;
      image = renderer_->render(scene.input(), options);
    }
    py::array_t<std::uint8_t> pixels(
        {static_cast<py::ssize_t>(height), static_cast<py::ssize_t>(width), py::ssize_t{3}});
    auto out = pixels.mutable_unchecked<3>();
    for (int y = 0; y < height; ++y) {
      for (int x = 0; x < width; ++x) {
        const Rgba& pixel = image.at(x, y);
        out(y, x, 0) = pixel.r;
        out(y, x, 1) = pixel.g;
        out(y, x, 2) = pixel.b;
      }
    }
    return pixels;
#else
    (void)width;
    (void)height;
    (void)mode_name;
    throw Error("render: this incise was built without OpenGL (INCISE_WITH_GL=OFF)");
#endif
  }

  template <typename Result>
  Result read(const std::function<Result(const Engine&)>& get) {
    const EngineLock lock(mutex_);
    return get(*engine_);
  }

 private:
  [[nodiscard]] std::uint64_t topology_stamp() const {
    return (generation_ << 40U) ^ engine_->mesh().revision();
  }
  static py::array shared_points(const std::shared_ptr<std::vector<Vec3>>& data) {
    return points_view(*data, keeper(data));
  }
  void replace(std::unique_ptr<Engine> engine) {
    engine_ = std::move(engine);
    live_ = nullptr;  // the live source went with the old engine; set_blade makes a new one
    ++generation_;
    ++stamp_;
  }

  std::mutex mutex_;
  std::unique_ptr<Engine> engine_;
  LiveToolPose* live_ = nullptr;  ///< the engine's tool source when set from Python
  std::uint64_t stamp_ = 1;       ///< moves on whenever the state may have changed
  std::uint64_t generation_ = 0;  ///< engines replaced by restore()
  Mirror<Vec3> positions_;
  Mirror<Vec3> velocities_;
  Mirror<Vec3> rest_;
  Mirror<Tet> tets_;
#ifdef INCISE_HAVE_GL
  std::unique_ptr<OffscreenRenderer> renderer_;
#endif
  std::optional<Camera> camera_;
  double camera_aspect_ = 0.0;
};

namespace {

py::dict frame_dict(const FrameRecord& r) {
  py::dict out;
  out["frame"] = r.frame;
  out["time"] = r.time;
  out["cd"] = r.cd;
  out["gc"] = r.gc;
  out["rx"] = r.rx;
  out["rd"] = r.rd;
  out["solver_iterations"] = r.solver_iterations;
  out["vertices"] = r.vertices;
  out["tets"] = r.tets;
  out["kinetic_energy"] = r.kinetic_energy;
  out["max_displacement"] = r.max_displacement;
  out["cut"] = r.cut;
  out["edited"] = r.edited;
  return out;
}

}  // namespace

void bind_simulation(py::module_& module) {
  py::class_<FrameRecord>(module, "Frame",
                          "One frame's record: stage times (s) named after Bielser et al.'s "
                          "Table 1 (cd collision detection, gc topology and geometry changes, "
                          "rx relaxation, rd output), the solver's iterations, and whether the "
                          "blade cut (`cut`) and the mesh changed (`edited`).")
      .def_readonly("frame", &FrameRecord::frame)
      .def_readonly("time", &FrameRecord::time, "simulated time at the end of the frame (s)")
      .def_readonly("cd", &FrameRecord::cd, "collision detection (s)")
      .def_readonly("gc", &FrameRecord::gc, "topology and geometry changes (s)")
      .def_readonly("rx", &FrameRecord::rx, "relaxation (s)")
      .def_readonly("rd", &FrameRecord::rd, "output (s)")
      .def_readonly("solver_iterations", &FrameRecord::solver_iterations)
      .def_readonly("vertices", &FrameRecord::vertices)
      .def_readonly("tets", &FrameRecord::tets)
      .def_readonly("kinetic_energy", &FrameRecord::kinetic_energy, "J")
      .def_readonly("max_displacement", &FrameRecord::max_displacement,
                    "largest distance from the rest position (m)")
      .def_readonly("cut", &FrameRecord::cut, "the blade moved with a cutter this frame")
      .def_readonly("edited", &FrameRecord::edited, "the mesh changed this frame")
      .def_property_readonly(
          "rx_parts",
          [](const FrameRecord& r) {
            return py::dict(
                py::arg("refresh") = r.rx_parts.refresh, py::arg("forces") = r.rx_parts.forces,
                py::arg("preconditioner") = r.rx_parts.preconditioner,
                py::arg("start") = r.rx_parts.start, py::arg("products") = r.rx_parts.products,
                py::arg("vector_updates") = r.rx_parts.vector_updates);
          },
          "where rx went (s): implicit schemes only")
      .def("as_dict", &frame_dict, "The record as a dict (a row for pandas).")
      .def("__repr__", [](const FrameRecord& r) {
        return "<incise.Frame " + std::to_string(r.frame) + " t=" + std::to_string(r.time) +
               " s, rx=" + std::to_string(1e3 * r.rx) + " ms" + (r.edited ? ", edited" : "") + ">";
      });

  py::class_<Simulation>(
      module, "Simulation",
      "A scene stepped frame by frame: Simulation(scene) with a scene file's path, a dict with "
      "the same keys (scenes/README.md), or None for the default scene. A bad key raises "
      "InputError naming it.\n\n"
      "Arrays (positions, velocities, rest_positions, tets) are read-only numpy arrays that "
      "keep the values of the frame they were taken in, whatever happens after (a cut that "
      "adds vertices, a restore); taking one twice in a frame copies nothing.\n\n"
      "Thread rule: every method may be called from any Python thread; calls on one simulation "
      "run one at a time, and step(), restore() and render() release the GIL while they work.")
      .def(py::init([](const py::object& scene, std::optional<std::filesystem::path> scene_file) {
             SceneDescription description = scene_from(scene, scene_file);
             py::gil_scoped_release release;
             return std::make_unique<Simulation>(std::make_unique<Engine>(description));
           }),
           py::arg("scene") = py::none(), py::arg("scene_file") = py::none(),
           "scene: a path, a dict (scene keys, SI units) or None (the default scene). "
           "scene_file: for a dict, the file it stands for: errors name it and relative paths "
           "resolve against its folder (default: the working folder).")
      .def_static(
          "resume",
          [](const std::filesystem::path& path) {
            py::gil_scoped_release release;
            return std::make_unique<Simulation>(Engine::resume(path));
          },
          py::arg("path"),
          "A simulation continuing from a checkpoint file (sim.checkpoint or incise run "
          "--checkpoint): the same frames afterwards, bit for bit.")
      .def("step", &Simulation::step, py::arg("frames") = py::none(),
           "step() advances one frame and returns its Frame; step(n) advances n frames and "
           "returns their list. The GIL is released meanwhile. Raises Diverged (and steps no "
           "further) when the simulation diverges.")
      .def_property_readonly("positions", &Simulation::positions,
                             "(n, 3) float64 current positions (m), read-only")
      .def_property_readonly("velocities", &Simulation::velocities,
                             "(n, 3) float64 velocities (m/s), read-only")
      .def_property_readonly("rest_positions", &Simulation::rest_positions,
                             "(n, 3) float64 rest positions (m), read-only")
      .def_property_readonly("tets", &Simulation::tets, "(m, 4) int32 tetrahedra, read-only")
      .def_property_readonly("labels", &Simulation::labels, "(m,) region label per tetrahedron")
      .def_property_readonly("mesh", &Simulation::mesh,
                             "A copy of the current mesh (rest shape) as an incise.Mesh")
      .def_property_readonly(
          "frame",
          [](Simulation& s) { return s.read<int>([](const Engine& e) { return e.frame(); }); },
          "frames stepped so far")
      .def_property_readonly(
          "time",
          [](Simulation& s) { return s.read<double>([](const Engine& e) { return e.time(); }); },
          "simulated time (s)")
      .def_property_readonly(
          "total_mass",
          [](Simulation& s) {
            return s.read<double>([](const Engine& e) { return e.total_mass(); });
          },
          "kg")
      .def_property_readonly(
          "frames",
          [](Simulation& s) {
            return s.read<int>([](const Engine& e) { return e.scene().frames; });
          },
          "the scene's `frames`: how long `incise run` runs it")
      .def_property_readonly(
          "inverted_tets",
          [](Simulation& s) {
            return s.read<std::size_t>(
                [](const Engine& e) { return inverted_at(e.mesh(), e.positions()).size(); });
          },
          "tetrahedra inside out in the current positions")
      .def_property_readonly(
          "guarded_tets",
          [](Simulation& s) {
            return s.read<std::uint64_t>([](const Engine& e) { return e.guarded_tets(); });
          },
          "tetrahedra the inversion guard pushed back right side out, over the steps so far")
      .def_property_readonly(
          "warnings",
          [](Simulation& s) {
            return s.read<std::vector<std::string>>([](const Engine& e) { return e.warnings(); });
          },
          "warnings about the scene (e.g. a step beyond the stability limit)")
      .def_property_readonly(
          "blade",
          [](Simulation& s) {
            return s.read<py::object>([](const Engine& e) -> py::object {
              const auto& blade = e.blade_rest();
              if (!blade) {
                return py::none();
              }
              return py::make_tuple(
                  py::make_tuple(blade->tip.x(), blade->tip.y(), blade->tip.z()),
                  py::make_tuple(blade->base.x(), blade->base.y(), blade->base.z()));
            });
          },
          "the blade at the end of the last frame in the rest frame, (tip, base) in m, or None")
      .def("set_blade", &Simulation::set_blade, py::arg("tip"), py::arg("base"),
           py::arg("frame") = "rest",
           "Puts the blade at tip-base (m) for the next step(): in the body's rest frame "
           "('rest', default) or where the body is now ('world'). Consecutive poses sweep a cut "
           "with a cutter in the scene (its `cutter` key). Replaces the scene's scripted path.")
      .def("lift_blade", &Simulation::lift_blade,
           "The blade leaves the body: the next set_blade starts a new stroke.")
      .def("push", &Simulation::push, py::arg("triangle"), py::arg("barycentric"), py::arg("force"),
           "Pushes with `force` (N, 3 floats) during the next step at a point of a collision "
           "(or visual) surface triangle given by barycentric coordinates.")
      .def("save_state", &Simulation::save_state,
           "The complete state as bytes (what a checkpoint file holds), for restore(): the "
           "frames after a restore are those after the save, bit for bit. A push or blade pose "
           "set but not yet stepped is not part of it.")
      .def("restore", &Simulation::restore, py::arg("state"),
           "Returns to a state from save_state() (of a simulation of any scene). Arrays taken "
           "before keep their values.")
      .def("checkpoint", &Simulation::checkpoint, py::arg("path"),
           "Writes the complete state to a file (atomically), for Simulation.resume(path).")
      .def("render", &Simulation::render, py::arg("width") = 640, py::arg("height") = 480,
           py::arg("mode") = "faces",
           "A picture of the current frame as an (height, width, 3) uint8 array, through the "
           "offscreen OpenGL renderer (EGL): mode 'faces' (textured), 'wire' or 'cut' (cut "
           "faces only). The camera is the scene's `camera`, else fitted to the body at the "
           "first picture of that shape and kept.");
}

}  // namespace incise::python
