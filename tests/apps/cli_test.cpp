// The incise command line, run as a user would: exit codes, JSON, messages on stderr.

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>
#include <thread>
#include <tuple>

#include "incise/render/image.hpp"
#include "planning/tissue_support.hpp"
#include "test_support.hpp"

namespace incise {
namespace {

struct CommandResult {
  int code = -1;
  std::string out;
  std::string err;
};

CommandResult incise(const std::string& arguments) {
  const auto dir = test::scratch_dir("cli-run");
  const std::string command = std::string(INCISE_EXECUTABLE) + " " + arguments + " >" +
                              (dir / "out").string() + " 2>" + (dir / "err").string();
  const int status = std::system(command.c_str());
  CommandResult run;
  run.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  run.out = test::file_bytes(dir / "out");
  run.err = test::file_bytes(dir / "err");
  return run;
}

std::string data(const std::string& relative) {
  return test::data_file(relative).string();
}

bool have_data() {
  return std::filesystem::exists(test::data_file("sofa/liver.msh"));
}

TEST(Cli, HelpOnEveryCommand) {
  for (const char* command :
       {"", "info", "convert", "generate", "generate box", "mesh", "run", "cut"}) {
    const CommandResult run = incise(std::string(command) + " --help");
    EXPECT_EQ(run.code, 0) << command;
    EXPECT_NE(run.out.find("Usage"), std::string::npos) << command << ": " << run.out;
  }
}

TEST(Cli, NoArgumentsSaysWhereToStart) {
  const CommandResult run = incise("");
  EXPECT_NE(run.code, 0);  // a command is needed
  EXPECT_NE(run.out.find("Start here"), std::string::npos) << run.out;
  for (const char* command : {"incise run", "incise view", "incise plan", "incise serve"}) {
    EXPECT_NE(run.out.find(command), std::string::npos) << command;
  }
}

/// Every command's help ends with its units and an example; the examples of the commands that
/// need neither a display nor a device run, in order, in one folder (they use each other's
/// files: the block generated first, the blade path the run records).
TEST(Cli, EveryHelpExampleRuns) {
  const auto dir = test::scratch_dir("help-examples");
  std::filesystem::create_directory_symlink(std::filesystem::path(INCISE_SOURCE_DIR) / "scenes",
                                            dir / "scenes");
  const auto in_folder = [&](const std::string& arguments) {
    const std::string command = "cd " + dir.string() + " && " + INCISE_EXECUTABLE + " " +
                                arguments + " >" + (dir / "out.txt").string() + " 2>" +
                                (dir / "err.txt").string();
    const int status = std::system(command.c_str());
    return std::pair{WIFEXITED(status) ? WEXITSTATUS(status) : -1,
                     test::file_bytes(dir / "err.txt")};
  };
  int ran = 0;
  for (const char* name : {"generate box", "info", "convert", "mesh", "run", "cut", "plan", "soak",
                           "view", "serve", "device"}) {
    const CommandResult help = incise(std::string(name) + " --help");
    if (help.code != 0 && (std::string(name) == "serve" || std::string(name) == "device")) {
      continue;  // built without OpenIGTLink
    }
    ASSERT_EQ(help.code, 0) << name;
    EXPECT_NE(help.out.find("\nUnits: "), std::string::npos) << name << ":\n" << help.out;
    std::istringstream lines(help.out);
    std::vector<std::string> examples;
    for (std::string line; std::getline(lines, line);) {
      if (line.rfind("Example: incise ", 0) == 0) {
        examples.push_back(line.substr(std::string("Example: incise ").size()));
      }
    }
    ASSERT_FALSE(examples.empty()) << name << ":\n" << help.out;
    const std::string command = name;
    if (command == "view" || command == "serve" || command == "device") {
      continue;  // a display, or a device and a server at once: run by their own tests
    }
    for (const std::string& example : examples) {
      const auto [code, err] = in_folder(example);
      EXPECT_EQ(code, 0) << "incise " << example << ":\n" << err;
      ++ran;
    }
  }
  EXPECT_GE(ran, 9);
  EXPECT_TRUE(std::filesystem::exists(dir / "cut.vtu"));
  EXPECT_TRUE(std::filesystem::exists(dir / "plan" / "report.json"));
}

TEST(Cli, NoOrUnknownCommandFails) {
  EXPECT_NE(incise("").code, 0);
  const CommandResult run = incise("dissect");
  EXPECT_NE(run.code, 0);
  EXPECT_FALSE(run.err.empty());
}

TEST(Cli, InfoJsonOnTheLiver) {
  if (!have_data()) {
    GTEST_SKIP();
  }
  const CommandResult run = incise("info --json " + data("sofa/liver.msh"));
  ASSERT_EQ(run.code, 0) << run.err;
  const auto json = nlohmann::json::parse(run.out);
  for (const char* key : {"vertices", "tets", "volume", "inverted", "degenerate",
                          "nonmanifold_faces", "components", "boundary_triangles", "watertight"}) {
    EXPECT_TRUE(json.contains(key)) << key;
  }
  EXPECT_EQ(json["vertices"], 181);
  EXPECT_EQ(json["tets"], 596);
  EXPECT_NEAR(json["volume"].template get<double>(), 36.56085106149485, 1e-10);
  EXPECT_EQ(json["inverted"], 0);
  EXPECT_EQ(json["components"], 1);
  EXPECT_EQ(json["watertight"], true);
  EXPECT_EQ(json["valid"], true);
}

TEST(Cli, InfoExitsOneOnInvalidMeshes) {
  if (!have_data()) {
    GTEST_SKIP();
  }
  for (const char* file : {"sofa/single_tetra.msh", "sofa/6_tetra_bad.msh"}) {
    const CommandResult run = incise("info --json " + data(file));
    EXPECT_EQ(run.code, 1) << file;
    const auto json = nlohmann::json::parse(run.out);
    EXPECT_EQ(json["inverted"], 1) << file;
    EXPECT_EQ(json["valid"], false);
  }
  const CommandResult text = incise("info " + data("sofa/6_tetra_bad.msh"));
  EXPECT_EQ(text.code, 1);
  EXPECT_NE(text.out.find("inverted tetrahedra"), std::string::npos) << text.out;
}

TEST(Cli, InfoOnEveryTetMeshInTheData) {
  if (!have_data()) {
    GTEST_SKIP();
  }
  for (const char* file : {"sofa/liver.msh", "sofa/cylinder.msh", "sofa/cube_low_res.msh",
                           "sofa-mor/liverTinyMesh.vtu", "sofa-mor/liverSemiFine.vtu",
                           "pbd/armadillo_4k.ele", "libigl/octopus-low.mesh"}) {
    const CommandResult run = incise("info " + data(file));
    EXPECT_EQ(run.code, 0) << file << ": " << run.err;
    EXPECT_NE(run.out.find("valid: yes"), std::string::npos) << run.out;
  }
}

TEST(Cli, ErrorsNameTheFileAndLine) {
  const auto dir = test::scratch_dir("cli-errors");
  std::ofstream(dir / "broken.msh")
      << "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n2\n1 0 0 0\n2 x 0 0\n";
  const CommandResult run = incise("info " + (dir / "broken.msh").string());
  EXPECT_EQ(run.code, 2);
  EXPECT_NE(run.err.find("broken.msh:7"), std::string::npos) << run.err;
  EXPECT_TRUE(run.out.empty());
  const CommandResult missing = incise("info " + (dir / "missing.msh").string());
  EXPECT_NE(missing.code, 0);
  EXPECT_FALSE(missing.err.empty());
}

TEST(Cli, ConvertFixesOrientation) {
  if (!have_data()) {
    GTEST_SKIP();
  }
  const auto dir = test::scratch_dir("cli-convert");
  const std::string fixed = (dir / "fixed.vtu").string();
  const CommandResult run =
      incise("convert " + data("sofa/single_tetra.msh") + " " + fixed + " --fix-orientation");
  ASSERT_EQ(run.code, 0) << run.err;
  EXPECT_NE(run.err.find("flipped 1"), std::string::npos) << run.err;
  const auto json = nlohmann::json::parse(incise("info --json " + fixed).out);
  EXPECT_EQ(json["inverted"], 0);
  EXPECT_NEAR(json["volume"].template get<double>(), 12.5, 1e-12);
  // Without the flag the mesh is converted as it is, with a warning.
  const CommandResult plain =
      incise("convert " + data("sofa/single_tetra.msh") + " " + (dir / "plain.msh").string());
  EXPECT_EQ(plain.code, 0);
  EXPECT_NE(plain.err.find("not valid"), std::string::npos) << plain.err;
}

TEST(Cli, ConvertChainKeepsTheMesh) {
  if (!have_data()) {
    GTEST_SKIP();
  }
  const auto dir = test::scratch_dir("cli-chain");
  std::string previous = data("libigl/octopus-low.mesh");
  for (const char* name : {"a.msh", "b.vtu", "c.node", "d.mesh"}) {
    const std::string next = (dir / name).string();
    ASSERT_EQ(incise("convert " + previous + " " + next).code, 0) << name;
    previous = next;
  }
  const auto json = nlohmann::json::parse(incise("info --json " + previous).out);
  EXPECT_EQ(json["tets"], 1140);
  EXPECT_EQ(json["vertices"], 452);
  EXPECT_NEAR(json["volume"].template get<double>(), 0.009135547847518207, 1e-15);
}

TEST(Cli, GenerateBox) {
  const auto dir = test::scratch_dir("cli-generate");
  const std::string out = (dir / "box.msh").string();
  const CommandResult run =
      incise("generate box --cells 2 3 4 --size 0.02 0.03 0.04 --tets-per-cell 5 -o " + out);
  ASSERT_EQ(run.code, 0) << run.err;
  const auto json = nlohmann::json::parse(incise("info --json " + out).out);
  EXPECT_EQ(json["tets"], 2 * 3 * 4 * 5);
  EXPECT_NEAR(json["volume"].template get<double>(), 0.02 * 0.03 * 0.04, 1e-15);
  EXPECT_EQ(json["valid"], true);
  EXPECT_NE(incise("generate box --tets-per-cell 4 -o " + out).code, 0);
  EXPECT_NE(incise("generate box --cells 0 1 1 -o " + out).code, 0);
}

TEST(Cli, MeshTheLiverSurfaceAndRepairAnOpenOne) {
  if (!have_data()) {
    GTEST_SKIP();
  }
  const auto dir = test::scratch_dir("cli-mesh");
  const std::string out = (dir / "liver.vtu").string();
  const CommandResult run =
      incise("mesh " + data("sofa/liver.obj") + " -o " + out + " --max-volume 0.05");
  ASSERT_EQ(run.code, 0) << run.err;
  const auto json = nlohmann::json::parse(incise("info --json " + out).out);
  EXPECT_EQ(json["valid"], true);
  EXPECT_GT(json["tets"].template get<int>(), 596);
  // An open surface: the liver with one triangle removed.
  std::ifstream in(data("sofa/liver.obj"));
  std::ofstream open_surface(dir / "open.obj");
  bool dropped = false;
  for (std::string line; std::getline(in, line);) {
    if (!dropped && line.rfind("f ", 0) == 0) {
      dropped = true;
      continue;
    }
    open_surface << line << "\n";
  }
  open_surface.close();
  // Refused as it is (--repair none), naming the open edges; repaired by default.
  const CommandResult open = incise("mesh " + (dir / "open.obj").string() + " -o " +
                                    (dir / "x.vtu").string() + " --repair none");
  EXPECT_EQ(open.code, 2);
  EXPECT_NE(open.err.find("open edges"), std::string::npos) << open.err;
  const CommandResult repaired =
      incise("mesh " + (dir / "open.obj").string() + " -o " + (dir / "x.vtu").string() +
             " --report " + (dir / "mesh.json").string());
  EXPECT_EQ(repaired.code, 0) << repaired.err;
  EXPECT_NE(repaired.err.find("repair: filled 1 holes"), std::string::npos) << repaired.err;
  const auto described = nlohmann::json::parse(test::file_bytes(dir / "mesh.json"));
  EXPECT_EQ(described["repair"]["holes_filled"], 1);
  EXPECT_GT(described["repair"]["hole_area"].get<double>(), 0.0);
  EXPECT_FALSE(described["repair"]["wrapped"].get<bool>());
  EXPECT_TRUE(described["valid"].get<bool>());
  EXPECT_EQ(nlohmann::json::parse(incise("info --json " + (dir / "x.vtu").string()).out)["valid"],
            true);
}

/// Writes `scene` as dir/scene.json, runs it with its frames in dir/out, and returns the run's
/// report (an empty object, with a test failure, when the run fails).
nlohmann::json run_scene(const std::filesystem::path& dir, const std::string& scene) {
  std::ofstream(dir / "scene.json") << scene;
  const CommandResult run =
      incise("run " + (dir / "scene.json").string() + " --out " + (dir / "out").string() +
             " --report " + (dir / "report.json").string());
  EXPECT_EQ(run.code, 0) << run.err;
  return run.code == 0 ? nlohmann::json::parse(test::file_bytes(dir / "report.json"))
                       : nlohmann::json::object();
}

TEST(Cli, AMeshWithASliverIsDescribedCutAndSimulatedNotRefused) {
  // Two tetrahedra (m): a regular one and, on its bottom face, a sliver whose apex lies 1e-9
  // below that face's middle (positive volume, normalised volume ~1e-8, as the tutorial
  // bunny's tetrahedron 11291). Every command takes it, and says it has a sliver.
  const auto dir = test::scratch_dir("cli-sliver");
  {
    std::ofstream mesh(dir / "sliver.mesh");
    mesh << "MeshVersionFormatted 2\nDimension 3\nVertices\n5\n"
         << "0 0 0 0\n0.01 0 0 0\n0 0.01 0 0\n0 0 0.01 0\n0.0033 0.0033 -1e-9 0\n"
         << "Tetrahedra\n2\n1 2 3 4 1\n1 3 2 5 1\nEnd\n";
  }
  const CommandResult info = incise("info --json " + (dir / "sliver.mesh").string());
  ASSERT_EQ(info.code, 0) << info.out << info.err;
  const auto described = nlohmann::json::parse(info.out);
  EXPECT_TRUE(described["valid"].get<bool>());
  EXPECT_EQ(described["slivers"].get<int>(), 1);
  EXPECT_EQ(described["degenerate"].get<int>(), 0);
  // The repair, for who wants the sliver gone: collapsed away, saying so.
  const std::string fixed = (dir / "fixed.vtu").string();
  const CommandResult convert =
      incise("convert " + (dir / "sliver.mesh").string() + " " + fixed + " --fix-slivers");
  ASSERT_EQ(convert.code, 0) << convert.err;
  EXPECT_NE(convert.err.find("1 edges collapsed, 0 flat and 0 slivers left"), std::string::npos)
      << convert.err;
  const auto described_fixed = nlohmann::json::parse(incise("info --json " + fixed).out);
  EXPECT_EQ(described_fixed["slivers"].get<int>(), 0);
  EXPECT_TRUE(described_fixed["valid"].get<bool>());
  {
    std::ofstream path(dir / "path.csv");
    path << "t,tip_x,tip_y,tip_z,base_x,base_y,base_z\n"
         << "0,-0.002,0.003,-0.001,-0.002,0.003,0.011\n"
         << "1,0.012,0.003,-0.001,0.012,0.003,0.011\n";
  }
  for (const char* method : {"subdivision", "xfem"}) {
    const CommandResult cut =
        incise("cut " + (dir / "sliver.mesh").string() + " --blade " + (dir / "path.csv").string() +
               " --method " + method + " -o " + (dir / (std::string(method) + ".vtu")).string());
    EXPECT_EQ(cut.code, 0) << method << ": " << cut.err;
    EXPECT_NE(cut.err.find("1 slivers"), std::string::npos) << cut.err;
  }
  const nlohmann::json report =
      run_scene(dir, R"({"mesh": {"file": "sliver.mesh"}, "material": "liver",
                 "model": {"type": "mass-spring"}, "fixed": [{"box": [[-1, -1, -1], [1, 1, 0.0001]]}],
                 "frames": 5, "frame_dt": 0.01, "output": {"dir": "out", "vtu_every": 5}})");
  ASSERT_FALSE(report.empty());
  EXPECT_FALSE(report["diverged"].get<bool>());
}

TEST(Cli, EverySceneDescriptionNamesOnlyFilesTheSceneWrites) {
  // A description that names an output file (out/DIR/NAME) must name one the scene writes:
  // each such scene is run for a frame into a scratch folder, and every file named is there.
  int named = 0;
  for (const auto& entry : std::filesystem::directory_iterator(INCISE_SOURCE_DIR "/scenes")) {
    if (entry.path().extension() != ".json") {
      continue;
    }
    const auto scene = nlohmann::json::parse(test::file_bytes(entry.path()));
    if (!scene.contains("description") || !scene.contains("output")) {
      continue;
    }
    const std::string description = scene["description"].get<std::string>();
    const std::regex file_pattern(R"(out/[A-Za-z0-9_]+/([A-Za-z0-9_.]+\.(pvd|vtu|vtp)))");
    std::vector<std::string> files;
    for (auto it = std::sregex_iterator(description.begin(), description.end(), file_pattern);
         it != std::sregex_iterator(); ++it) {
      files.push_back((*it)[1].str());
    }
    if (files.empty()) {
      continue;
    }
    const auto dir = test::scratch_dir("described-" + entry.path().stem().string());
    const CommandResult run =
        incise("run " + entry.path().string() + " --frames 1 --out " + dir.string());
    ASSERT_EQ(run.code, 0) << run.err;
    for (const std::string& file : files) {
      ++named;
      EXPECT_TRUE(std::filesystem::exists(dir / file))
          << entry.path().filename() << "'s description names " << file << ", not written";
    }
  }
  EXPECT_GT(named, 0);
}

TEST(Cli, BrokenSurfacesOfEveryKindAreMeshedAndCutApart) {
  // Unit cubes (0..1) written as OBJ files with one defect each; `incise mesh` repairs each and
  // a planar blade through x = 0.25 cuts the body in two.
  const auto dir = test::scratch_dir("cli-mesh-broken");
  const auto cube_at = [](double x, double y, double z) {
    std::ostringstream text;
    for (int k = 0; k < 8; ++k) {
      text << "v " << (k & 1) + x << " " << ((k >> 1) & 1) + y << " " << ((k >> 2) & 1) + z << "\n";
    }
    return text.str();
  };
  const auto cube = [&](double shift) { return cube_at(shift, shift, shift); };
  // The cube's 12 outward triangles (1-based, offset by `base`), `skip` left out, `flip` turned.
  const auto faces = [](int base, int skip, int flip) {
    const int triangles[12][3] = {{1, 3, 4}, {1, 4, 2}, {5, 6, 8}, {5, 8, 7}, {1, 2, 6}, {1, 6, 5},
                                  {3, 7, 8}, {3, 8, 4}, {1, 5, 7}, {1, 7, 3}, {2, 4, 8}, {2, 8, 6}};
    std::ostringstream text;
    for (int t = 0; t < 12; ++t) {
      if (t == skip) {
        continue;
      }
      const int* f = triangles[t];
      const int second = t == flip ? f[2] : f[1];
      const int third = t == flip ? f[1] : f[2];
      text << "f " << f[0] + base << " " << second + base << " " << third + base << "\n";
    }
    return text.str();
  };
  const std::map<std::string, std::string> surfaces{
      {"hole", cube(0) + faces(0, 5, -1)},
      {"flipped", cube(0) + faces(0, -1, 3) + ""},
      {"duplicated", cube(0) + faces(0, -1, -1) + faces(0, -1, -1)},
      {"quads_open", cube(0) + "f 1 2 4 3\nf 5 7 8 6\nf 1 5 6 2\nf 3 4 8 7\nf 1 3 7 5\n"},
      {"self_intersecting", cube(0) + cube(0.5) + faces(0, -1, -1) + faces(8, -1, -1)},
      {"corner_touch", cube(0) + cube(1) + faces(0, -1, -1) + faces(8, -1, -1)},
      {"edge_touch", cube(0) + cube_at(1, 1, 0) + faces(0, -1, -1) + faces(8, -1, -1)}};
  {
    std::ofstream path(dir / "path.csv");
    path << "t,tip_x,tip_y,tip_z,base_x,base_y,base_z\n"
         << "0,0.25,-1,-1,0.25,-1,3\n"
         << "1,0.25,3,-1,0.25,3,3\n";
  }
  for (const auto& [name, text] : surfaces) {
    std::ofstream(dir / (name + ".obj")) << text;
    const std::string mesh = (dir / (name + ".vtu")).string();
    const CommandResult refused =
        incise("mesh " + (dir / (name + ".obj")).string() + " -o " + mesh + " --repair none");
    EXPECT_NE(refused.code, 0) << name;  // as before: refused
    const CommandResult meshed = incise("mesh " + (dir / (name + ".obj")).string() + " -o " + mesh +
                                        " --max-volume 0.01 --wrap-alpha 0.2");
    ASSERT_EQ(meshed.code, 0) << name << ": " << meshed.err;
    EXPECT_NE(meshed.err.find("repair: "), std::string::npos) << name << ": " << meshed.err;
    const std::string report = (dir / (name + ".json")).string();
    const CommandResult cut =
        incise("cut " + mesh + " --blade " + (dir / "path.csv").string() + " -o " +
               (dir / (name + "_cut.vtu")).string() + " --report " + report);
    ASSERT_EQ(cut.code, 0) << name << ": " << cut.err;
    const auto json = nlohmann::json::parse(test::file_bytes(report));
    EXPECT_TRUE(json["valid"].get<bool>()) << name;
    EXPECT_EQ(json["components"], 2) << name << ": " << cut.err;
  }
}

TEST(Cli, ARefusedSurfaceIsRepairedMeshedCutAndSimulated) {
  // SOFA's smooth liver surface intersects itself: `incise mesh` refused it. Now it is wrapped
  // (saying so, and how far the result lies from the input), and the body is cut and run.
  const auto dir = test::scratch_dir("cli-mesh-repair");
  const std::string surface = test::data_file("sofa/liver-smooth.obj").string();
  const std::string mesh = (dir / "liver.vtu").string();
  const CommandResult refused = incise("mesh " + surface + " -o " + mesh + " --repair none");
  EXPECT_NE(refused.code, 0);
  EXPECT_NE(refused.err.find("self-intersections"), std::string::npos) << refused.err;
  EXPECT_NE(refused.err.find("--repair auto"), std::string::npos) << refused.err;
  const CommandResult meshed = incise("mesh " + surface + " -o " + mesh + " --wrap-alpha 0.4");
  ASSERT_EQ(meshed.code, 0) << meshed.err;
  EXPECT_NE(meshed.err.find("alpha-wrapped"), std::string::npos) << meshed.err;
  EXPECT_NE(meshed.err.find("the result lies within"), std::string::npos) << meshed.err;
  {
    std::ofstream path(dir / "path.csv");
    path << "t,tip_x,tip_y,tip_z,base_x,base_y,base_z\n"
         << "0,-5.5,2.7,-2.5,-5.5,2.7,3.5\n"
         << "1,2.5,2.7,-2.5,2.5,2.7,3.5\n";  // through the whole liver
  }
  const CommandResult cut =
      incise("cut " + mesh + " --blade " + (dir / "path.csv").string() + " -o " +
             (dir / "cut.vtu").string() + " --report " + (dir / "cut.json").string());
  ASSERT_EQ(cut.code, 0) << cut.err;
  const auto cut_report = nlohmann::json::parse(test::file_bytes(dir / "cut.json"));
  EXPECT_TRUE(cut_report["valid"].get<bool>());
  EXPECT_EQ(cut_report["components"], 2);  // it separates
  const nlohmann::json report =
      run_scene(dir, R"({"mesh": {"file": "liver.vtu", "scale": 0.01}, "material": "liver",
                 "fixed": [{"box": [[-1, -1, -1], [1, 1, 0]]}], "gravity": [0, 0, -9.81],
                 "integrator": {"type": "backward-euler", "dt": 0.01},
                 "frames": 3, "frame_dt": 0.01, "output": {"dir": "out", "vtu_every": 3}})");
  ASSERT_FALSE(report.empty());
  EXPECT_FALSE(report["diverged"].get<bool>());
  EXPECT_EQ(report["inverted_tets"], 0);
}

TEST(Cli, TheVolumeTermKeepsTheDefaultSceneRightSideOut) {
  // The main job's scene (150 frames): with springs alone and no inversion guard 46 of its 936
  // tetrahedra end inside out, and the report counts them; with the mass-spring volume term,
  // or the guard, or both (the default) none does. `incise info` on the last frame tells the
  // state's inversion from a broken mesh: the mesh is valid in its rest shape either way.
  const auto dir = test::scratch_dir("cli-run-default-inverted");
  const std::string source = std::string(INCISE_SOURCE_DIR) + "/scenes/default.json";
  auto scene = nlohmann::json::parse(test::file_bytes(source));
  scene.erase("output");
  std::map<std::string, int> inverted;
  std::map<std::string, int> inverted_by_info;
  std::map<std::string, int> guarded;
  // name: volume_stiffness ("-": the default), inversion_guard (null: the default)
  const std::vector<std::tuple<std::string, std::string, nlohmann::json>> runs{
      {"springs", "0", false},
      {"guard", "0", nullptr},
      {"volume", "0.1", false},
      {"default", "-", nullptr}};
  for (const auto& run_spec : runs) {
    const std::string& name = std::get<0>(run_spec);
    const std::string& stiffness = std::get<1>(run_spec);
    const nlohmann::json& guard = std::get<2>(run_spec);
    scene["model"].erase("volume_stiffness");
    scene["model"].erase("inversion_guard");
    if (stiffness != "-") {
      scene["model"]["volume_stiffness"] = std::stod(stiffness);
    }
    if (!guard.is_null()) {
      scene["model"]["inversion_guard"] = guard;
    }
    const auto path = dir / ("scene_" + name + ".json");
    std::ofstream(path) << scene.dump();
    const std::string report = (dir / "report.json").string();
    const auto out = dir / ("out_" + name);
    const CommandResult run =
        incise("run " + path.string() + " --out " + out.string() + " --report " + report);
    ASSERT_EQ(run.code, 0) << run.err;
    const auto json = nlohmann::json::parse(test::file_bytes(report));
    ASSERT_TRUE(json.contains("inverted_tets"));
    EXPECT_GT(json["tets"].template get<int>(), 900);  // cut through
    inverted[name] = json["inverted_tets"].template get<int>();
    guarded[name] = json["guarded_tets"].template get<int>();
    std::filesystem::path last;
    for (const auto& entry : std::filesystem::directory_iterator(out)) {
      if (entry.path().extension() == ".vtu" &&
          entry.path().filename().string().find("clipped") == std::string::npos &&
          entry.path().filename() > last.filename()) {
        last = entry.path();
      }
    }
    const CommandResult info = incise("info --json " + last.string());
    EXPECT_EQ(info.code, 0) << info.out << info.err;  // a valid mesh, whatever its state
    const auto described = nlohmann::json::parse(info.out);
    EXPECT_TRUE(described["valid"].get<bool>()) << last;
    inverted_by_info[name] = described["inverted_in_positions"].get<int>();
  }
  EXPECT_GT(inverted["springs"], 0);
  EXPECT_EQ(inverted["guard"], 0);
  EXPECT_GT(guarded["guard"], 0);  // the guard did the work
  EXPECT_EQ(inverted["volume"], 0);
  EXPECT_EQ(guarded["volume"], 0);
  EXPECT_EQ(inverted["default"], 0);
  EXPECT_EQ(inverted_by_info["springs"], inverted["springs"]);
  EXPECT_EQ(inverted_by_info["default"], 0);
}

TEST(Cli, SoakCutsEndEveryFrameRightSideOut) {
  // Soak cases that ended frames with tetrahedra inside out before the inversion guard (seeds
  // of 2026-11-27): mass-spring grids 41, 51 and 64 (up to 5, 6 and 20 subdivision slivers,
  // with the volume term alone) and corotational FEM on the collapsing cylinder, seed 46 (up
  // to 1,024). The soak refuses any tetrahedron inside out after a frame, and none is.
  const auto dir = test::scratch_dir("cli-soak-right-side-out");
  for (const int seed : {41, 51, 64, 46}) {
    const auto out = dir / std::to_string(seed);
    const CommandResult run = incise("soak --seed " + std::to_string(seed) + " --cuts 1 --out " +
                                     out.string() + " --data " + test::data_dir().string());
    EXPECT_EQ(run.code, 0) << run.out << run.err;
    EXPECT_NE(run.out.find(seed == 46 ? "cylinder.msh (perturbed), subdivision + corotational-fem"
                                      : "subdivision + mass-spring"),
              std::string::npos)
        << run.out;
    const auto report = nlohmann::json::parse(test::file_bytes(out / "soak.json"));
    EXPECT_EQ(report["inverted_tets_max"], 0) << seed;
  }
}

TEST(Cli, RunTheDefaultSceneWithAReport) {
  const auto dir = test::scratch_dir("cli-run-default");
  const std::string report = (dir / "report.json").string();
  const CommandResult run =
      incise("run --frames 40 --out " + (dir / "out").string() + " --report " + report);
  ASSERT_EQ(run.code, 0) << run.err;
  for (const char* stage : {"cd", "gc", "rx", "rd"}) {
    EXPECT_NE(run.out.find(std::string("\n") + stage + " "), std::string::npos) << run.out;
  }
  const auto json = nlohmann::json::parse(test::file_bytes(report));
  for (const char* key : {"vertices", "tets", "kinetic_energy", "max_displacement", "diverged",
                          "mean_ms", "per_frame_ms"}) {
    EXPECT_TRUE(json.contains(key)) << key;
  }
  for (const char* stage : {"cd", "gc", "rx", "rd"}) {
    EXPECT_TRUE(json["mean_ms"].contains(stage)) << stage;
    EXPECT_TRUE(json["per_frame_ms"][0].contains(stage)) << stage;
  }
  EXPECT_GT(json["tets"].template get<int>(), 576);  // the blade has cut the block
  EXPECT_EQ(json["diverged"], false);
  EXPECT_EQ(json["per_frame_ms"].size(), 40u);
  EXPECT_EQ(json["per_frame_ms"][0]["solver_iterations"], 0);  // explicit: no linear solve
  EXPECT_EQ(json["per_frame_ms"][0]["rx_parts"]["products"], 0.0);
  EXPECT_TRUE(std::filesystem::exists(dir / "out" / "default.pvd"));
  EXPECT_TRUE(std::filesystem::exists(dir / "out" / "default_000040.vtu"));
}

TEST(Cli, SoakCutsWithEveryCutterAndModelAndFindsNoViolation) {
  // The short seeded soak CI runs: seeds 1-6 draw grids (regular and perturbed) and, with the
  // data, a real mesh; subdivision with mass-spring and with FEM, XFEM; random walks and a full
  // sweep that must separate. Every frame is checked (see command_soak.cpp).
  const auto dir = test::scratch_dir("cli-soak");
  const CommandResult run =
      incise("soak --seed 1 --cuts 6 --poses 20 --out " + (dir / "soak").string() + " --data " +
             test::data_dir().string());
  ASSERT_EQ(run.code, 0) << run.out << run.err;
  for (const char* kind : {"subdivision + mass-spring", "subdivision + corotational-fem",
                           "xfem + corotational-fem", "full sweep", "random walk"}) {
    EXPECT_NE(run.out.find(kind), std::string::npos) << kind << " never drawn:\n" << run.out;
  }
  const auto report = nlohmann::json::parse(test::file_bytes(dir / "soak" / "soak.json"));
  EXPECT_EQ(report["cuts"], 6);
  EXPECT_EQ(report["frames"], 6 * 20);
  EXPECT_EQ(report["violations"], 0);
  EXPECT_FALSE(std::filesystem::exists(dir / "soak" / "failures"));
}

TEST(Cli, AKilledRunLeavesEveryFrameItWroteAndItsCheckpointWhole) {
  // Nothing lost: a run killed with SIGKILL (no chance to clean up) part-way through leaves
  // every frame it finished, its series file and its checkpoint readable. What it was writing
  // at that moment stays a temporary beside them, never a truncated .vtu.
  const auto dir = test::scratch_dir("cli-killed");
  const auto out = dir / "out";
  const std::string checkpoint = (dir / "run.ck").string();
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    std::freopen("/dev/null", "w", stdout);
    std::freopen("/dev/null", "w", stderr);
    ::execl(INCISE_EXECUTABLE, "incise", "run", "--frames", "100000", "--out", out.string().c_str(),
            "--checkpoint", checkpoint.c_str(), "--checkpoint-every", "7",
            static_cast<char*>(nullptr));
    std::_Exit(127);
  }
  const auto frames_written = [&] {
    std::size_t count = 0;
    if (std::filesystem::exists(out)) {
      for (const auto& entry : std::filesystem::directory_iterator(out)) {
        count += entry.path().extension() == ".vtu" ? 1 : 0;
      }
    }
    return count;
  };
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  while (frames_written() < 6 && std::chrono::steady_clock::now() < give_up) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  ::kill(pid, SIGKILL);
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFSIGNALED(status)) << "the run ended before it was killed";
  ASSERT_GE(frames_written(), 6u);
  std::size_t temporaries = 0;
  for (const auto& entry : std::filesystem::directory_iterator(out)) {
    const std::string name = entry.path().filename().string();
    if (name.find(".tmp") != std::string::npos) {
      ++temporaries;
    } else if (entry.path().extension() == ".vtu") {
      // Read whole (exit 1 would only say the deformed frame has inverted elements, which a
      // mass-spring wound may have; a truncated or unreadable file exits 2).
      const CommandResult info = incise("info " + entry.path().string() + " --json");
      ASSERT_NE(info.code, 2) << name << ": " << info.err;
      EXPECT_GE(nlohmann::json::parse(info.out)["tets"].get<int>(), 576) << name;
    } else if (entry.path().extension() == ".pvd") {
      // Every frame it lists is there.
      const std::string series = test::file_bytes(entry.path());
      EXPECT_NE(series.find("</VTKFile>"), std::string::npos) << series;
      for (std::size_t at = series.find("file=\""); at != std::string::npos;
           at = series.find("file=\"", at + 1)) {
        const std::size_t start = at + 6;
        const std::string file = series.substr(start, series.find('"', start) - start);
        EXPECT_TRUE(std::filesystem::exists(out / file)) << file;
      }
    }
  }
  EXPECT_LE(temporaries, 2u) << "at most the frame and the checkpoint being written";
  const CommandResult resumed =
      incise("run --resume " + checkpoint + " --frames 2 --out " + (dir / "resumed").string());
  EXPECT_EQ(resumed.code, 0) << resumed.err;
}

/// `incise soak --replay` over the kept failure folders in tests/data/soak_findings/`which`.
CommandResult replay_soak_findings(const char* which) {
  std::string folders;
  for (const auto& entry : std::filesystem::directory_iterator(
           std::filesystem::path(INCISE_SOURCE_DIR) / "tests/data/soak_findings" / which)) {
    if (entry.is_directory()) {
      folders += " " + entry.path().string();
    }
  }
  return incise("soak --replay" + folders);
}

TEST(Cli, FixedSoakFindingsStayFixed) {
  // Cuts the soak once caught breaking a check (tests/data/soak_findings/README.md), checked
  // again with the soak's own checks after every frame.
  const CommandResult run = replay_soak_findings("fixed");
  EXPECT_EQ(run.code, 0) << run.out << run.err;
  EXPECT_NE(run.out.find("0 of 10 kept failures still fail"), std::string::npos) << run.out;
}

TEST(Cli, RunResumesFromACheckpointIntoTheSameSeries) {
  // 40 frames straight, against 27 frames with a checkpoint and 13 more resumed from it (the
  // blade is in the block at frame 27): the same .vtu files, one .pvd listing them all.
  const auto dir = test::scratch_dir("cli-resume");
  const std::string straight = (dir / "straight").string();
  const std::string parts = (dir / "parts").string();
  const std::string checkpoint = (dir / "run.ck").string();
  ASSERT_EQ(incise("run --frames 40 --out " + straight).code, 0);
  const CommandResult first = incise("run --frames 27 --out " + parts + " --checkpoint " +
                                     checkpoint + " --checkpoint-every 10");
  ASSERT_EQ(first.code, 0) << first.err;
  const CommandResult second = incise("run --resume " + checkpoint + " --frames 13 --out " + parts);
  ASSERT_EQ(second.code, 0) << second.err;
  EXPECT_NE(second.err.find("resumed at frame 27"), std::string::npos) << second.err;
  for (int frame = 0; frame <= 40; frame += 5) {
    const std::string name =
        "default_0000" + std::string(frame < 10 ? "0" : "") + std::to_string(frame) + ".vtu";
    EXPECT_EQ(test::file_bytes(dir / "straight" / name), test::file_bytes(dir / "parts" / name))
        << name;
  }
  const std::string pvd = test::file_bytes(dir / "parts" / "default.pvd");
  EXPECT_NE(pvd.find("default_000005.vtu"), std::string::npos) << pvd;
  EXPECT_NE(pvd.find("default_000040.vtu"), std::string::npos) << pvd;
  // A scene file beside --resume is refused; so is a damaged checkpoint.
  EXPECT_NE(incise("run --resume " + checkpoint + " " +
                   (std::filesystem::path(INCISE_SOURCE_DIR) / "scenes" / "default.json").string())
                .code,
            0);
  std::ofstream(dir / "bad.ck") << "INCISE-CHECKPOINT\ngarbage";
  const CommandResult bad = incise("run --resume " + (dir / "bad.ck").string());
  EXPECT_NE(bad.code, 0);
  EXPECT_NE(bad.err.find("bad.ck"), std::string::npos) << bad.err;
}

TEST(Cli, CutReportsWhatTheIssueAsks) {
  const auto dir = test::scratch_dir("cli-cut");
  const std::string mesh = (dir / "block.msh").string();
  ASSERT_EQ(incise("generate box --cells 4 6 4 --size 0.04 0.06 0.04 -o " + mesh).code, 0);
  std::ofstream path(dir / "blade.csv");
  path << "t,tip_x,tip_y,tip_z,base_x,base_y,base_z\n";
  for (int i = 0; i <= 10; ++i) {
    const double y = -0.01 + 0.08 * i / 10.0;
    path << 0.1 * i << ",0.0237," << y << ",-0.01,0.0237," << y << ",0.05\n";
  }
  path.close();
  const std::string report = (dir / "cut.json").string();
  const CommandResult run = incise("cut " + mesh + " --blade " + (dir / "blade.csv").string() +
                                   " -o " + (dir / "cut.vtu").string() + " --report " + report);
  ASSERT_EQ(run.code, 0) << run.err;
  const auto json = nlohmann::json::parse(test::file_bytes(report));
  for (const char* key :
       {"tets_in", "tets_out", "vertices_in", "vertices_out", "volume_in", "volume_out",
        "components", "watertight", "inverted_tets", "min_volume_ratio", "cut_area", "cd", "gc",
        "accumulated_cut_cases", "min_volume_ratio_to_original"}) {
    EXPECT_TRUE(json.contains(key)) << key;
  }
  EXPECT_EQ(json["tets_in"], 576);
  EXPECT_GT(json["min_volume_ratio_to_original"].template get<double>(), 0.0);
  EXPECT_GT(json["accumulated_cut_cases"]["A"].template get<int>() +
                json["accumulated_cut_cases"]["B"].template get<int>(),
            0);
  EXPECT_EQ(json["components"], 2);
  EXPECT_EQ(json["watertight"], true);
  EXPECT_EQ(json["inverted_tets"], 0);
  EXPECT_NEAR(json["cut_area"].template get<double>(), 0.06 * 0.04, 1e-12);
  EXPECT_NEAR(json["volume_out"].template get<double>(), json["volume_in"].template get<double>(),
              1e-15);
  const auto info = nlohmann::json::parse(incise("info --json " + (dir / "cut.vtu").string()).out);
  EXPECT_EQ(info["components"], 2);
  EXPECT_EQ(info["valid"], true);
}

TEST(Cli, RunReportsDivergenceWithExitCodeThree) {
  const auto dir = test::scratch_dir("cli-run-diverge");
  std::ofstream(dir / "bad.json")
      << R"({"mesh": {"box": {"cells": [2, 2, 2], "size": [0.01, 0.01, 0.01]}},
    "integrator": {"type": "symplectic-euler", "dt": 0.002},
    "fixed": [{"box": [[-1, -1, -1], [1, 1, 0]]}], "gravity": [0, 0, -9.81], "frames": 200})";
  const CommandResult run =
      incise("run " + (dir / "bad.json").string() + " --out " + (dir / "out").string());
  EXPECT_EQ(run.code, 3);
  EXPECT_NE(run.err.find("diverged"), std::string::npos) << run.err;
  EXPECT_NE(run.err.find("warning"), std::string::npos) << run.err;
}

TEST(Cli, RunRejectsUnknownSceneKeys) {
  const auto dir = test::scratch_dir("cli-run-keys");
  std::ofstream(dir / "typo.json")
      << "{\"mesh\": {\"box\": {\"cells\": [2, 2, 2]}},\n\"frmes\": 3}";
  const CommandResult run = incise("run " + (dir / "typo.json").string());
  EXPECT_EQ(run.code, 2);
  EXPECT_NE(run.err.find("typo.json:2"), std::string::npos) << run.err;
  EXPECT_NE(run.err.find("did you mean 'frames'"), std::string::npos) << run.err;
}

TEST(Cli, FemScenesRunAndGiveTheSameFramesWhateverTheThreadCount) {
  const auto dir = test::scratch_dir("cli-run-fem");
  const std::string scene = std::string(INCISE_SOURCE_DIR) + "/scenes/fem_box_sag.json";
  const CommandResult one =
      incise("run " + scene + " --frames 6 --threads 1 --out " + (dir / "one").string());
  ASSERT_EQ(one.code, 0) << one.err;
  const CommandResult two =
      incise("run " + scene + " --frames 6 --threads 2 --out " + (dir / "two").string());
  ASSERT_EQ(two.code, 0) << two.err;
  for (const char* frame : {"fem_box_sag_000005.vtu", "fem_box_sag_000006.vtu"}) {
    const std::string a = test::file_bytes(dir / "one" / frame);
    ASSERT_FALSE(a.empty()) << frame;
    EXPECT_EQ(a, test::file_bytes(dir / "two" / frame))
        << frame << " differs between 1 and 2 threads";
  }
  // The static cantilever: one Newton solve with a direct solver, a downward tip.
  const std::string report = (dir / "cantilever.json").string();
  const CommandResult cantilever =
      incise("run " + std::string(INCISE_SOURCE_DIR) + "/scenes/cantilever_static.json --out " +
             (dir / "cantilever").string() + " --report " + report);
  ASSERT_EQ(cantilever.code, 0) << cantilever.err;
  const auto json = nlohmann::json::parse(test::file_bytes(report));
  EXPECT_EQ(json["integrator"], "static");
  // 40 x 4 x 4 cells lock to 1.31 mm of the beam theory's 1.47 mm (see the accuracy tests).
  EXPECT_NEAR(json["max_displacement"].template get<double>(), 1.31e-3, 0.03e-3);
}

/// Width and height from a PNG's IHDR chunk (bytes 16-23, big-endian), or {0, 0}.
/// Whether a command failed only for want of offscreen OpenGL on this machine, and the suite
/// may skip for it (INCISE_REQUIRE_GL makes that a failure instead).
bool lacks_offscreen_gl(const CommandResult& run) {
  return run.code != 0 && run.err.find("offscreen rendering") != std::string::npos &&
         std::getenv("INCISE_REQUIRE_GL") == nullptr;
}

std::pair<int, int> png_size(const std::filesystem::path& path) {
  const std::string bytes = test::file_bytes(path);
  if (bytes.size() < 24 || bytes.compare(1, 3, "PNG") != 0) {
    return {0, 0};
  }
  const auto word = [&](std::size_t at) {
    int value = 0;
    for (std::size_t k = 0; k < 4; ++k) {
      value = value * 256 + static_cast<unsigned char>(bytes[at + k]);
    }
    return value;
  };
  return {word(16), word(20)};
}

TEST(Cli, RunRendersPicturesOfTheDefaultScene) {
  const auto dir = test::scratch_dir("render");
  const CommandResult run =
      incise("run --frames 10 --out " + (dir / "out").string() + " --render " +
             (dir / "png").string() + " --render-every 5 --size 160x120 --mode cut");
  if (lacks_offscreen_gl(run)) {
    GTEST_SKIP() << "no OpenGL here: " << run.err;
  }
  ASSERT_EQ(run.code, 0) << run.err;
  for (const char* name : {"frame_000000.png", "frame_000005.png", "frame_000010.png"}) {
    EXPECT_EQ(png_size(dir / "png" / name), std::make_pair(160, 120)) << name;
  }
  EXPECT_FALSE(std::filesystem::exists(dir / "png" / "frame_000001.png"));
  EXPECT_NE(run.out.find("pictures: 3"), std::string::npos) << run.out;
}

/// An icosphere written as OBJ (mm).
void write_sphere_obj(const std::filesystem::path& path, double radius_mm) {
  const SurfaceMesh sphere = testing::sphere(radius_mm, 3);
  std::ofstream out(path);
  for (const Vec3& p : sphere.points) {
    out << "v " << p.x() << " " << p.y() << " " << p.z() << "\n";
  }
  for (const Triangle& t : sphere.triangles) {
    out << "f " << t[0] + 1 << " " << t[1] + 1 << " " << t[2] + 1 << "\n";
  }
}

TEST(Cli, PlanDrawsTheSkinBeforeAfterAndColouredByItsDisplacement) {
  const auto dir = test::scratch_dir("plan-render");
  write_sphere_obj(dir / "skin.obj", 50.0);
  write_sphere_obj(dir / "bone.obj", 40.0);
  // The upper cap of the skull lifted 3 mm: the skin over it moves, the rest stays.
  std::ofstream(dir / "plan.json") << R"({
    "surfaces": {"skin": "skin.obj", "bone": "bone.obj"}, "layers": 2,
    "osteotomies": [{"point": [0, 0, 20], "normal": [0, 0, 1]}],
    "moves": [{"segment_near": [0, 0, 40], "translate": [0, 0, 3]}]
  })";
  const CommandResult run =
      incise("plan " + (dir / "plan.json").string() + " --out " + (dir / "out").string() +
             " --render " + (dir / "png").string() + " --size 200x150");
  if (lacks_offscreen_gl(run)) {
    GTEST_SKIP() << "no OpenGL here: " << run.err;
  }
  ASSERT_EQ(run.code, 0) << run.err;
  for (const char* name : {"skin_before.png", "skin_after.png", "skin_displacement.png",
                           "skin_displacement_frontal.png", "skin_displacement_lateral.png"}) {
    EXPECT_EQ(png_size(dir / "png" / name), std::make_pair(200, 150)) << name;
  }
  // Before and after side by side.
  EXPECT_EQ(png_size(dir / "png" / "skin_before_after.png"), std::make_pair(400, 150));
  // Each picture says what it shows: light text in its top left corner (a title and the view's
  // name), where the renderer leaves only its dark background.
  for (const char* name : {"skin_before.png", "skin_displacement_lateral.png"}) {
    const Image labelled = read_png(dir / "png" / name);
    std::size_t ink = 0;
    for (int y = 0; y < 30; ++y) {
      for (int x = 0; x < 100; ++x) {
        const Rgba p = labelled.at(x, y);
        ink += p.r > 200 && p.g > 200 && p.b > 200 ? 1 : 0;
      }
    }
    EXPECT_GT(ink, 50U) << name;
  }
  EXPECT_NE(run.out.find("mm red"), std::string::npos) << run.out;
  // The camera faces the moved skin: red in the middle, over the lifted cap, blue towards the
  // rim, where the skin beside the cut stays.
  const Image picture = read_png(dir / "png" / "skin_displacement.png");
  const Rgba middle = picture.at(100, 75);
  EXPECT_GT(middle.r, middle.b + 60);
  std::size_t red = 0;
  std::size_t blue = 0;
  for (const Rgba& p : picture.pixels()) {
    red += p.r > p.b + 60 ? 1 : 0;
    blue += p.b > p.r + 20 ? 1 : 0;  // the background is greyer
  }
  EXPECT_GT(red, 2000U);
  EXPECT_GT(blue, 50U);
  // A colour bar at the right edge: red at the top (the largest displacement), blue at the
  // bottom (0 mm), a column of the map between its labels.
  int bar_x = -1;
  for (int x = picture.width() - 1; x > picture.width() / 2 && bar_x < 0; --x) {
    const Rgba top = picture.at(x, picture.height() / 4);
    const Rgba bottom = picture.at(x, picture.height() - 35);
    if (top.r > top.b + 60 && bottom.b > bottom.r + 60) {
      bar_x = x;
    }
  }
  EXPECT_GT(bar_x, picture.width() * 3 / 4) << "no colour bar at the right edge";
  // Picture options are checked before anything runs.
  const CommandResult bad =
      incise("plan " + (dir / "plan.json").string() + " --out " + (dir / "out2").string() +
             " --render " + (dir / "png2").string() + " --size 10x");
  EXPECT_EQ(bad.code, 2);
  EXPECT_NE(bad.err.find("--size"), std::string::npos) << bad.err;
  EXPECT_FALSE(std::filesystem::exists(dir / "out2" / "report.json"));
}

TEST(Cli, RunRefusesBadPictureOptionsByName) {
  const auto dir = test::scratch_dir("render-bad");
  const std::string render =
      " --frames 1 --out " + (dir / "out").string() + " --render " + (dir / "png").string();
  for (const auto& [arguments, named] : std::vector<std::pair<std::string, std::string>>{
           {render + " --size 10x", "--size"},
           {render + " --size 4x4", "--size"},
           {render + " --mode sideways", "--mode"},
           {" --frames 1 --size 100x100", "--render"},
           {" --frames 1 --video a.mp4", "--render"}}) {
    const CommandResult run = incise("run" + arguments);
    EXPECT_EQ(run.code, 2) << arguments;
    EXPECT_NE(run.err.find(named), std::string::npos) << arguments << ": " << run.err;
  }
  EXPECT_FALSE(std::filesystem::exists(dir / "png" / "frame_000000.png"));
}

TEST(Cli, ViewPacedNeedsExitAfter) {
  const CommandResult run = incise("view --paced");
  EXPECT_EQ(run.code, 2);
  EXPECT_NE(run.err.find("--exit-after"), std::string::npos) << run.err;
}

/// A pixel of cut tissue in a picture: deep red, unlike background, blade and exterior.
std::size_t cut_pixels(const std::filesystem::path& png) {
  std::size_t n = 0;
  const Image image = read_png(png);
  for (const Rgba& p : image.pixels()) {
    n += p.r > 40 && p.r > 2 * p.g && p.r > 2 * p.b ? 1 : 0;
  }
  return n;
}

bool have_xvfb() {
  return std::system("command -v xvfb-run >/dev/null 2>&1") == 0;
}

/// `incise ARGUMENTS` in a virtual X server, its output into `output`; its exit code.
int incise_under_xvfb(const std::string& arguments, const std::filesystem::path& output) {
  const std::string command = "xvfb-run -a -s '-screen 0 1280x1024x24' " +
                              std::string(INCISE_EXECUTABLE) + " " + arguments + " >" +
                              output.string() + " 2>&1";
  const int status = std::system(command.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST(Cli, ViewReplaysAHandMadeCutUnderXvfbAndRunReplaysItBitForBit) {
  // tests/data/mouse_cut.jsonl: incise view on the default scene, recorded with the mouse (the
  // scene's own cut, then a diagonal stroke by hand at frame 80), 116 frames.
  if (!have_xvfb()) {
    if (std::getenv("INCISE_REQUIRE_GL") != nullptr) {
      FAIL() << "INCISE_REQUIRE_GL is set and xvfb-run is missing (apt-get install xvfb)";
    }
    GTEST_SKIP() << "no xvfb-run here";
  }
  const auto dir = test::scratch_dir("view");
  const std::string recording = std::string(INCISE_SOURCE_DIR) + "/tests/data/mouse_cut.jsonl";
  const auto view = [&](const std::string& arguments) {
    return incise_under_xvfb("view --replay " + recording + " --size 640x480 " + arguments,
                             dir / "view.out");
  };
  ASSERT_EQ(view("--exit-after 0 --mode cut --screenshot " + (dir / "first.png").string()), 0)
      << test::file_bytes(dir / "view.out");
  ASSERT_EQ(view("--exit-after 116 --mode cut --screenshot " + (dir / "last.png").string() +
                 " --out " + (dir / "view").string()),
            0)
      << test::file_bytes(dir / "view.out");
  EXPECT_EQ(cut_pixels(dir / "first.png"), 0u);
  EXPECT_GT(cut_pixels(dir / "last.png"), 300u);
  // Without a window, the same recording gives the same final mesh, byte for byte.
  const CommandResult run =
      incise("run --replay " + recording + " --out " + (dir / "run").string());
  ASSERT_EQ(run.code, 0) << run.err;
  const std::string from_view = test::file_bytes(dir / "view" / "default_000116.vtu");
  EXPECT_GT(from_view.size(), 1000u);
  EXPECT_EQ(from_view, test::file_bytes(dir / "run" / "default_000116.vtu"));
}

TEST(Cli, PlanViewNudgesSegmentsStopsThemAtContactAndSavesWhatPlanReproduces) {
  if (!have_xvfb()) {
    if (std::getenv("INCISE_REQUIRE_GL") != nullptr) {
      FAIL() << "INCISE_REQUIRE_GL is set and xvfb-run is missing (apt-get install xvfb)";
    }
    GTEST_SKIP() << "no xvfb-run here";
  }
  const auto dir = test::scratch_dir("plan-view");
  write_sphere_obj(dir / "skin.obj", 50.0);
  write_sphere_obj(dir / "bone.obj", 40.0);
  std::ofstream(dir / "plan.json") << R"({
    "surfaces": {"skin": "skin.obj", "bone": "bone.obj"}, "layers": 2,
    "osteotomies": [{"point": [0, 0, 20], "normal": [0, 0, 1]}]
  })";
  // A session as a surgeon makes it: the skull's cap (segment 1) lifted 1 mm twice, tilted
  // 3 degrees, then pushed 8 mm down into the rest of the skull, and the plan saved.
  const std::string saved = (dir / "saved.json").string();
  std::ofstream(dir / "session.json") << R"({"plan": "plan.json", "requests": [
    {"nudge": {"segment": 1, "translate_mm": [0, 0, 1], "rotate_deg": [0, 0, 0]}},
    {"nudge": {"segment": 1, "translate_mm": [0, 0, 1], "rotate_deg": [0, 0, 0]}},
    {"nudge": {"segment": 1, "translate_mm": [0, 0, 0], "rotate_deg": [0, 3, 0]}},
    {"nudge": {"segment": 1, "translate_mm": [0, 0, -8], "rotate_deg": [0, 0, 0]}},
    {"save": ")" + saved + R"("}]})";
  const auto view = [&](const std::string& name) {
    return incise_under_xvfb(
        "plan " + (dir / "plan.json").string() + " --view --size 800x600 --replay " +
            (dir / "session.json").string() + " --record " + (dir / (name + ".json")).string() +
            " --screenshot " + (dir / (name + ".png")).string(),
        dir / (name + ".out"));
  };
  ASSERT_EQ(view("first"), 0) << test::file_bytes(dir / "first.out");
  ASSERT_EQ(view("second"), 0) << test::file_bytes(dir / "second.out");
  // One prediction to start and one per nudge that moved; the same session gives the same
  // prediction, bit for bit (the largest displacement printed to 17 digits), and records
  // itself as it was played.
  const std::string out = test::file_bytes(dir / "first.out");
  EXPECT_NE(out.find("5 predictions"), std::string::npos) << out;
  EXPECT_EQ(out, test::file_bytes(dir / "second.out"));
  EXPECT_EQ(nlohmann::json::parse(test::file_bytes(dir / "first.json"))["requests"],
            nlohmann::json::parse(test::file_bytes(dir / "session.json"))["requests"]);
  // The window showed the skin coloured by its displacement (red over the lifted cap) and the
  // panel.
  const Image picture = read_png(dir / "first.png");
  EXPECT_EQ(picture.width(), 800);
  std::size_t red = 0;
  for (const Rgba& p : picture.pixels()) {
    red += p.r > p.b + 60 ? 1 : 0;
  }
  EXPECT_GT(red, 500U);
  // The push down stopped at contact: the cap stays above where it started, below 2 mm.
  const auto plan = nlohmann::json::parse(test::file_bytes(dir / "saved.json"));
  ASSERT_EQ(plan["moves"].size(), 1u);
  const double lifted = plan["moves"][0]["translate"][2].get<double>();
  EXPECT_GT(lifted, 0.0);
  EXPECT_LT(lifted, 2.0);
  EXPECT_DOUBLE_EQ(plan["moves"][0]["rotate"]["angle_deg"].get<double>(), 3.0);
  // incise plan runs the saved plan to the prediction the window showed (warm-started there,
  // from the scan here: within the solver's tolerance).
  const CommandResult run = incise("plan " + saved + " --out " + (dir / "out").string());
  ASSERT_EQ(run.code, 0) << run.err;
  const auto report = nlohmann::json::parse(test::file_bytes(dir / "out" / "report.json"));
  const std::size_t at = out.rfind("largest skin displacement ");
  ASSERT_NE(at, std::string::npos);
  const double shown = std::stod(out.substr(at + 26));
  EXPECT_GT(shown, 0.5);
  EXPECT_NEAR(report["max_displacement"].get<double>(), shown, 1e-3);
  // A plan that moves the cap already: the window starts from that move, and a nudge adds to it.
  std::ofstream(dir / "moved.json") << R"({
    "surfaces": {"skin": "skin.obj", "bone": "bone.obj"}, "layers": 2,
    "osteotomies": [{"point": [0, 0, 20], "normal": [0, 0, 1]}],
    "moves": [{"segment_near": [0, 0, 40], "translate": [0, 0, 2]}]
  })";
  const std::string saved_moved = (dir / "saved_moved.json").string();
  std::ofstream(dir / "nudge.json") << R"({"plan": "moved.json", "requests": [
    {"nudge": {"segment": 1, "translate_mm": [0, 0, 1], "rotate_deg": [0, 0, 0]}},
    {"save": ")" + saved_moved + R"("}]})";
  ASSERT_EQ(
      incise_under_xvfb("plan " + (dir / "moved.json").string() +
                            " --view --size 640x480 --replay " + (dir / "nudge.json").string(),
                        dir / "moved.out"),
      0)
      << test::file_bytes(dir / "moved.out");
  const auto added = nlohmann::json::parse(test::file_bytes(saved_moved));
  ASSERT_EQ(added["moves"].size(), 1u);
  EXPECT_NEAR(added["moves"][0]["translate"][2].get<double>(), 3.0, 1e-9);
}

// A plan with no osteotomy: a plane placed by hand in the window cuts the skull, the cap it
// makes is nudged, and the saved plan (the plane and the move in it) is what incise plan runs.
TEST(Cli, PlanViewCutsTheBoneByAPlanePlacedByHandAndSavesIt) {
  if (!have_xvfb()) {
    if (std::getenv("INCISE_REQUIRE_GL") != nullptr) {
      FAIL() << "INCISE_REQUIRE_GL is set and xvfb-run is missing (apt-get install xvfb)";
    }
    GTEST_SKIP() << "no xvfb-run here";
  }
  const auto dir = test::scratch_dir("plan-view-cut");
  write_sphere_obj(dir / "skin.obj", 50.0);
  write_sphere_obj(dir / "bone.obj", 40.0);
  std::ofstream(dir / "plan.json") << R"({
    "surfaces": {"skin": "skin.obj", "bone": "bone.obj"}, "layers": 2
  })";
  const std::string saved = (dir / "saved.json").string();
  // A plane tilted 10 degrees about x through (0, 0, 20) mm; then the cap lifted 1.5 mm.
  std::ofstream(dir / "session.json") << R"({"plan": "plan.json", "requests": [
    {"cut": {"point_mm": [0, 0, 20], "normal": [0, -0.17364817766693033, 0.984807753012208]}},
    {"nudge": {"segment": 1, "translate_mm": [0, 0, 1.5], "rotate_deg": [0, 0, 0]}},
    {"save": ")" + saved + R"("}]})";
  ASSERT_EQ(
      incise_under_xvfb("plan " + (dir / "plan.json").string() +
                            " --view --size 800x600 --replay " + (dir / "session.json").string() +
                            " --record " + (dir / "recorded.json").string(),
                        dir / "view.out"),
      0)
      << test::file_bytes(dir / "view.out");
  const std::string out = test::file_bytes(dir / "view.out");
  // One prediction to start, one after the cut, one after the nudge.
  EXPECT_NE(out.find("3 predictions"), std::string::npos) << out;
  EXPECT_EQ(nlohmann::json::parse(test::file_bytes(dir / "recorded.json"))["requests"],
            nlohmann::json::parse(test::file_bytes(dir / "session.json"))["requests"]);
  const auto plan = nlohmann::json::parse(test::file_bytes(saved));
  ASSERT_EQ(plan["osteotomies"].size(), 1u);
  EXPECT_NEAR(plan["osteotomies"][0]["point"][2].get<double>(), 20.0, 1e-12);
  EXPECT_NEAR(plan["osteotomies"][0]["normal"][1].get<double>(), -0.17364817766693033, 1e-12);
  ASSERT_EQ(plan["moves"].size(), 1u);
  EXPECT_NEAR(plan["moves"][0]["translate"][2].get<double>(), 1.5, 1e-9);
  // The move is the cap's: its point lies above the plane.
  const Vec3 near(plan["moves"][0]["segment_near"][0].get<double>(),
                  plan["moves"][0]["segment_near"][1].get<double>(),
                  plan["moves"][0]["segment_near"][2].get<double>());
  EXPECT_GT((near - Vec3(0, 0, 20)).dot(Vec3(0, -0.17364817766693033, 0.984807753012208)), 0.0);
  const CommandResult run = incise("plan " + saved + " --out " + (dir / "out").string());
  ASSERT_EQ(run.code, 0) << run.err;
  const auto report = nlohmann::json::parse(test::file_bytes(dir / "out" / "report.json"));
  EXPECT_EQ(report["segments"].get<int>(), 2);
  const std::size_t at = out.rfind("largest skin displacement ");
  ASSERT_NE(at, std::string::npos);
  const double shown = std::stod(out.substr(at + 26));
  EXPECT_GT(shown, 0.5);
  EXPECT_NEAR(report["max_displacement"].get<double>(), shown, 1e-3);
}

TEST(Cli, ReplayRefusesABadRecordingByLine) {
  const auto dir = test::scratch_dir("bad-replay");
  std::ofstream(dir / "bad.jsonl") << "{\"incise_session\": 1}\n{\"frame\": 0}\n";
  const CommandResult run = incise("run --replay " + (dir / "bad.jsonl").string());
  EXPECT_EQ(run.code, 2);
  EXPECT_NE(run.err.find("bad.jsonl:2"), std::string::npos) << run.err;
}

TEST(Cli, RunWritesAVideoThroughFfmpegOrSaysItIsMissing) {
  const auto dir = test::scratch_dir("video");
  const std::string arguments = "run --frames 12 --out " + (dir / "out").string() + " --render " +
                                (dir / "png").string() + " --size 161x121 --video " +
                                (dir / "cut.mp4").string();
  // Without ffmpeg on PATH: a clear error before anything is drawn.
  const std::string command = "PATH=" + (dir / "empty").string() + " " + INCISE_EXECUTABLE + " " +
                              arguments + " 2>" + (dir / "err").string() + " >/dev/null";
  const int status = std::system(command.c_str());
  EXPECT_EQ(WIFEXITED(status) ? WEXITSTATUS(status) : -1, 2);
  EXPECT_NE(test::file_bytes(dir / "err").find("needs the ffmpeg program"), std::string::npos)
      << test::file_bytes(dir / "err");
  if (std::system("command -v ffmpeg >/dev/null 2>&1") != 0) {
    GTEST_SKIP() << "ffmpeg is not installed here (apt-get install ffmpeg)";
  }
  const CommandResult run = incise(arguments);
  if (lacks_offscreen_gl(run)) {
    GTEST_SKIP() << "no OpenGL here";
  }
  ASSERT_EQ(run.code, 0) << run.err;
  const std::string video = test::file_bytes(dir / "cut.mp4");
  ASSERT_GT(video.size(), 1000u);
  EXPECT_EQ(video.substr(4, 4), "ftyp");  // an MP4 container
}

/// The default scene's stroke (a vertical blade along y at x = 0.0213), from y = -0.012 at
/// t = 0 to `end_y` at `end_time` (s).
void write_stroke(const std::filesystem::path& path, double end_time, double end_y) {
  std::ofstream stroke(path);
  stroke << "t,tip_x,tip_y,tip_z,base_x,base_y,base_z\n"
         << "0.0,0.0213,-0.012,0.012,0.0213,-0.012,0.06\n"
         << end_time << ",0.0213," << end_y << ",0.012,0.0213," << end_y << ",0.06\n";
}

/// Starts `incise serve --port 0 FLAGS` in the background (its pid in DIR/pid, its output in
/// DIR/serve.log) and returns the port it listens on, or "" when it did not say in 10 s.
std::string start_server(const std::filesystem::path& dir, const std::string& flags) {
  const std::string serve = "bash -c '" + std::string(INCISE_EXECUTABLE) +
                            " serve --port 0 --port-file " + (dir / "port").string() + " " + flags +
                            " >" + (dir / "serve.log").string() + " 2>&1 & echo $! >" +
                            (dir / "pid").string() + "'";
  if (std::system(serve.c_str()) != 0) {
    return "";
  }
  std::string port;
  for (int i = 0; i < 200 && port.empty(); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    port = test::file_bytes(dir / "port");
  }
  return port.substr(0, port.find('\n'));
}

/// Waits up to 30 s for `path` to appear.
bool appears(const std::filesystem::path& path) {
  for (int i = 0; i < 600 && !std::filesystem::exists(path); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return std::filesystem::exists(path);
}

TEST(Cli, ServeAndDeviceCutTheDefaultBlockOverLoopback) {
  if (incise("serve --help").code != 0) {
    GTEST_SKIP() << "built without OpenIGTLink";
  }
  const auto dir = test::scratch_dir("serve");
  // The default scene's stroke, played by the device process in real time (1 s).
  write_stroke(dir / "path.csv", 1.0, 0.072);
  if (test::kSanitized) {
    // A cutting frame takes about 1 s under ASan (12 ms unsanitized), 2-3 s on a loaded CI
    // machine: the 1 s stroke can be over before a frame has built a contact model with the
    // blade in the tissue (CI of session 32: no force above 0.1 N). So the blade stops halfway
    // for 4 s: whatever the frame rate, the haptic loop then renders contact from a model
    // built around a still blade.
    std::ofstream stroke(dir / "path.csv");
    stroke << "t,tip_x,tip_y,tip_z,base_x,base_y,base_z\n"
           << "0.0,0.0213,-0.012,0.012,0.0213,-0.012,0.06\n"
           << "0.5,0.0213,0.03,0.012,0.0213,0.03,0.06\n"
           << "4.5,0.0213,0.03,0.012,0.0213,0.03,0.06\n"
           << "5.0,0.0213,0.072,0.012,0.0213,0.072,0.06\n";
  }
  const std::string port =
      start_server(dir, "--exit-when-idle --max-seconds 60 --out " + (dir / "out").string());
  ASSERT_FALSE(port.empty()) << test::file_bytes(dir / "serve.log");
  const CommandResult device = incise("device " + (dir / "path.csv").string() + " --port " + port +
                                      " --log " + (dir / "forces.csv").string());
  ASSERT_EQ(device.code, 0) << device.err;
  EXPECT_NE(device.out.find("forces received"), std::string::npos) << device.out;
  // The server notices the device left, writes its results and exits.
  ASSERT_TRUE(appears(dir / "out" / "report.json")) << test::file_bytes(dir / "serve.log");
  const auto report = nlohmann::json::parse(test::file_bytes(dir / "out" / "report.json"));
  EXPECT_EQ(report["ended"], "idle (the last device left)");
  EXPECT_TRUE(report["valid"].get<bool>());
  EXPECT_TRUE(report["watertight"].get<bool>());
  EXPECT_NEAR(report["rest_volume_m3"].get<double>(), report["rest_volume_start_m3"].get<double>(),
              1e-12 * report["rest_volume_start_m3"].get<double>());
  EXPECT_GT(report["tets"].get<int>(), report["tets_start"].get<int>());  // it was cut
  // The deformed state's inside-out elements are counted, and there are none (the served cut
  // of the landed code of session 28 ended with 36 of 1,578 with springs alone, of session 29
  // with 0-2 slivers inside out with the volume term alone): the inversion guard says what it
  // pushed back.
  ASSERT_TRUE(report.contains("inverted_tets"));
  ASSERT_TRUE(report.contains("guarded_tets"));
  std::printf("served cut: %d of %d tetrahedra inside out, %d pushed back\n",
              report["inverted_tets"].get<int>(), report["tets"].get<int>(),
              report["guarded_tets"].get<int>());
  EXPECT_EQ(report["inverted_tets"], 0);
  EXPECT_GT(report["messages"]["poses"].get<int>(), 500);
  EXPECT_EQ(report["messages"]["dropped_total"].get<int>(), 0);
  EXPECT_GT(report["haptic"]["ticks"].get<int>(), 500);
  EXPECT_LE(report["haptic"]["largest_force_n"].get<double>(), 3.0 + 1e-9);
  // The final mesh is on disk (deformed: mass-spring tissue may invert slivers, so incise info
  // may call it invalid) and closed as incise info sees it; report.json judged its topology.
  const CommandResult info = incise("info --json " + (dir / "out" / "final.vtu").string());
  ASSERT_LE(info.code, 1) << info.err;
  const auto mesh = nlohmann::json::parse(info.out);
  EXPECT_TRUE(mesh["watertight"].get<bool>());
  EXPECT_EQ(mesh["nonmanifold_faces"], 0);
  // Forces were logged: a header, one row per force, some in contact, none above the limit.
  std::ifstream forces(dir / "forces.csv");
  std::string line;
  std::getline(forces, line);
  EXPECT_EQ(line, "t,fx,fy,fz");
  int rows = 0;
  int in_contact = 0;
  while (std::getline(forces, line)) {
    double t = 0;
    double fx = 0;
    double fy = 0;
    double fz = 0;
    ASSERT_EQ(std::sscanf(line.c_str(), "%lf,%lf,%lf,%lf", &t, &fx, &fy, &fz), 4) << line;
    const double magnitude = std::sqrt(fx * fx + fy * fy + fz * fz);
    EXPECT_LE(magnitude, 3.0 + 1e-6);
    in_contact += magnitude > 0.1 ? 1 : 0;
    ++rows;
  }
  EXPECT_GT(rows, 500);
  EXPECT_GT(in_contact, 100);
}

TEST(Cli, ServeAnXfemSceneTheTissueFeelsTheDevicesReaction) {
  if (incise("serve --help").code != 0) {
    GTEST_SKIP() << "built without OpenIGTLink";
  }
  if (test::kSanitized) {
    // A 4,500-tet XFEM frame takes about 2 s under ASan: the 1 s stroke is over before the
    // first frame ends. The unsanitized build runs this test.
    GTEST_SKIP() << "real time: not under a sanitizer";
  }
  const auto dir = test::scratch_dir("serve-xfem");
  // The skin patch's stroke: 5 mm deep along y across it, played by the device in 3 s (a
  // machine loaded by the rest of the suite runs few physics frames a second; in 1 s the
  // stroke was sometimes over before a tetrahedron split).
  {
    std::ofstream stroke(dir / "path.csv");
    stroke << "t,tip_x,tip_y,tip_z,base_x,base_y,base_z\n"
           << "0.0,0.0317,-0.006,0.005,0.0317,-0.006,0.03\n"
           << "3.0,0.0317,0.046,0.005,0.0317,0.046,0.03\n";
  }
  const std::string scene = std::string(INCISE_SOURCE_DIR) + "/scenes/xfem_skin.json";
  const std::string port = start_server(
      dir, scene + " --exit-when-idle --max-seconds 60 --out " + (dir / "out").string());
  ASSERT_FALSE(port.empty()) << test::file_bytes(dir / "serve.log");
  const CommandResult device = incise("device " + (dir / "path.csv").string() + " --port " + port);
  ASSERT_EQ(device.code, 0) << device.err;
  ASSERT_TRUE(appears(dir / "out" / "report.json")) << test::file_bytes(dir / "serve.log");
  const auto report = nlohmann::json::parse(test::file_bytes(dir / "out" / "report.json"));
  EXPECT_TRUE(report["valid"].get<bool>());
  EXPECT_GT(report["tets"].get<int>(), report["tets_start"].get<int>());  // virtual elements
  // The device felt the skin, and the skin felt the device back, on its collision surface.
  EXPECT_GT(report["haptic"]["largest_force_n"].get<double>(), 0.0);
  // (How many frames push depends on how many physics frames a loaded machine runs while the
  // blade is in the skin: 16-20 of about 55 here; any is the mechanism working.)
  EXPECT_GT(report["haptic"]["reaction_pushes"].get<int>(), 0);
  EXPECT_GT(report["haptic"]["largest_reaction_n"].get<double>(), 0.0);
}

TEST(Cli, ServeOutlivesItsClientsAndWritesItsResultsOnSigterm) {
  if (incise("serve --help").code != 0) {
    GTEST_SKIP() << "built without OpenIGTLink";
  }
  const auto dir = test::scratch_dir("serve-sigterm");
  write_stroke(dir / "path.csv", 0.3, 0.02);
  const std::string port = start_server(dir, "--max-seconds 60 --out " + (dir / "out").string());
  ASSERT_FALSE(port.empty()) << test::file_bytes(dir / "serve.log");
  // A client that sends only garbage, then leaves.
  const std::string garbage =
      "bash -c 'head -c 4096 /dev/urandom >/dev/tcp/127.0.0.1/" + port + "' 2>/dev/null";
  (void)std::system(garbage.c_str());  // the server may close on it mid-stream: that is fine
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  // Two devices, one after the other: the session goes on.
  for (int i = 0; i < 2; ++i) {
    const CommandResult device =
        incise("device " + (dir / "path.csv").string() + " --port " + port + " --hold 0.1");
    ASSERT_EQ(device.code, 0) << device.err;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  EXPECT_FALSE(std::filesystem::exists(dir / "out" / "report.json"));
  const std::string pid = test::file_bytes(dir / "pid");
  ASSERT_EQ(std::system(("kill -TERM " + pid.substr(0, pid.find('\n'))).c_str()), 0);
  ASSERT_TRUE(appears(dir / "out" / "report.json")) << test::file_bytes(dir / "serve.log");
  const auto report = nlohmann::json::parse(test::file_bytes(dir / "out" / "report.json"));
  // (Under a sanitizer a frame can outlast the 0.7 s the server waits: it then says it
  // abandoned that frame, after the same words.)
  EXPECT_EQ(report["ended"].get<std::string>().rfind("stopped (SIGINT/SIGTERM)", 0), 0u)
      << report["ended"];
  EXPECT_EQ(report["clients"].get<int>(), 3);
  EXPECT_GT(report["messages"]["dropped_total"].get<int>(), 0);  // the garbage, counted
  EXPECT_GT(report["messages"]["poses"].get<int>(), 400);        // both devices' poses
  EXPECT_TRUE(report["valid"].get<bool>());
  EXPECT_TRUE(std::filesystem::exists(dir / "out" / "final.vtu"));
}

TEST(Cli, ServeAnswersSigtermWithinASecondEvenInTheMiddleOfALongFrame) {
  if (incise("serve --help").code != 0) {
    GTEST_SKIP() << "built without OpenIGTLink";
  }
  const auto dir = test::scratch_dir("serve-long-frame");
  // The default block stepped explicitly at dt = 10 ns: a frame (10 ms of tissue) takes about
  // a minute, so a signal always arrives inside one.
  {
    std::ofstream scene(dir / "slow.json");
    scene << R"({"mesh": {"box": {"cells": [4, 6, 4], "size": [0.04, 0.06, 0.04]}},
                "model": {"type": "mass-spring"},
                "integrator": {"type": "explicit-euler", "dt": 1e-8},
                "fixed": [{"box": [[-1, -1, -1], [0.0001, 1, 1]]}],
                "tool": {"poses": [[0, 0.02, -0.01, 0.01, 0.02, -0.01, 0.06]]},
                "cutter": {"type": "subdivision"}, "frames": 100, "frame_dt": 0.01})";
  }
  const std::string port = start_server(
      dir, (dir / "slow.json").string() + " --max-seconds 600 --out " + (dir / "out").string());
  ASSERT_FALSE(port.empty()) << test::file_bytes(dir / "serve.log");
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // inside the first frame
  const std::string pid_line = test::file_bytes(dir / "pid");
  const std::string pid = pid_line.substr(0, pid_line.find('\n'));
  const auto signalled = std::chrono::steady_clock::now();
  ASSERT_EQ(std::system(("kill -TERM " + pid).c_str()), 0);
  // Its files written, and gone, long before the frame could have ended (the grace is 0.7 s;
  // the bound leaves a margin for a loaded machine).
  const auto report_path = dir / "out" / "report.json";
  while (!std::filesystem::exists(report_path) &&
         std::chrono::steady_clock::now() - signalled < std::chrono::seconds(10)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  const double waited =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - signalled).count();
  bool gone = false;
  for (int i = 0; i < 500 && !gone; ++i) {
    gone = kill(std::stoi(pid), 0) != 0;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  if (!gone) {
    (void)std::system(("kill -KILL " + pid).c_str());
  }
  ASSERT_TRUE(std::filesystem::exists(report_path)) << test::file_bytes(dir / "serve.log");
  std::printf("incise serve wrote its report %.2f s after SIGTERM\n", waited);
  EXPECT_LT(waited, 5.0);
  EXPECT_TRUE(gone) << test::file_bytes(dir / "serve.log");
  const auto report = nlohmann::json::parse(test::file_bytes(dir / "out" / "report.json"));
  EXPECT_NE(report["ended"].get<std::string>().find("abandoned"), std::string::npos)
      << report["ended"];
  EXPECT_EQ(report["frames"].get<int>(), 0);
  EXPECT_TRUE(report["valid"].get<bool>());
  EXPECT_TRUE(std::filesystem::exists(dir / "out" / "final.vtu"));
  const CommandResult info = incise("info --json " + (dir / "out" / "final.vtu").string());
  EXPECT_EQ(info.code, 0) << info.err;
}

TEST(Cli, CutWithXfemSeparatesTheLiverWithFewerDofs) {
  if (!have_data()) {
    GTEST_SKIP();
  }
  const auto dir = test::scratch_dir("cut-xfem");
  // Issue 11's full cut: vertical blade across the liver at 0.513 of its y-extent.
  {
    std::ofstream path(dir / "path.csv");
    path << "t,tip_x,tip_y,tip_z,base_x,base_y,base_z\n";
    const double y = 0.217888 + 0.513 * (5.15717 - 0.217888);
    for (int i = 0; i <= 24; ++i) {
      const double x = -5.17928 + (1.80331 + 4.67928 + 1.0) * i / 24.0;
      path << 0.04 * i << "," << x << "," << y << ",-2.2," << x << "," << y << ",3.3\n";
    }
  }
  const std::string common =
      "cut " + data("sofa/liver.msh") + " --blade " + (dir / "path.csv").string() + " ";
  const CommandResult xfem = incise(common + "--method xfem -o " + (dir / "xfem.vtu").string() +
                                    " --report " + (dir / "xfem.json").string());
  ASSERT_EQ(xfem.code, 0) << xfem.err;
  const CommandResult subdivision = incise(common + "-o " + (dir / "sub.vtu").string() +
                                           " --report " + (dir / "sub.json").string());
  ASSERT_EQ(subdivision.code, 0) << subdivision.err;
  const auto x = nlohmann::json::parse(test::file_bytes(dir / "xfem.json"));
  const auto s = nlohmann::json::parse(test::file_bytes(dir / "sub.json"));
  EXPECT_EQ(x["components"], 2);
  EXPECT_EQ(s["components"], 2);
  EXPECT_NEAR(x["volume_out"].get<double>(), x["volume_in"].get<double>(),
              1e-12 * x["volume_in"].get<double>());
  EXPECT_EQ(x["tets_out"].get<int>(), x["tets_in"].get<int>() + x["elements_split"].get<int>());
  // XFEM adds at most a third of the subdivision cutter's degrees of freedom on this cut.
  const int subdivision_dofs = 3 * (s["vertices_out"].get<int>() - s["vertices_in"].get<int>());
  EXPECT_GT(x["dofs_added"].get<int>(), 0);
  EXPECT_LE(3 * x["dofs_added"].get<int>(), subdivision_dofs);
  // The virtual elements are readable, fractions and all.
  const CommandResult info = incise("info --json " + (dir / "xfem.vtu").string());
  ASSERT_LE(info.code, 1) << info.err;  // virtual elements overlap in rest space by design
  const auto described = nlohmann::json::parse(info.out);
  EXPECT_EQ(described["tets"], x["tets_out"]);
  // incise info weighs each virtual element by its fraction: the liver's true volume, not
  // the overlapping elements' (which count every split tetrahedron twice).
  EXPECT_NEAR(described["volume"].get<double>(), x["volume_out"].get<double>(),
              1e-9 * x["volume_out"].get<double>());
  EXPECT_EQ(described["virtual_elements"].get<int>(), 2 * x["elements_split"].get<int>());
  // Beside the file, the elements clipped to their sides, and the report says where.
  EXPECT_TRUE(std::filesystem::exists(dir / "xfem_clipped.vtu"));
  EXPECT_NEAR(x["clipped_volume"].get<double>(), x["volume_in"].get<double>(),
              1e-9 * x["volume_in"].get<double>());
  // Anything but .vtu is refused with a clear message.
  const CommandResult obj = incise(common + "--method xfem -o " + (dir / "x.obj").string());
  EXPECT_EQ(obj.code, 2);
  EXPECT_NE(obj.err.find(".vtu"), std::string::npos) << obj.err;

  // SOFA's visual liver, which sticks out of liver.msh, cut with it: closed, its volume kept.
  const CommandResult with_visual =
      incise(common + "--method xfem -o " + (dir / "xv.vtu").string() + " --visual " +
             data("sofa/liver-smooth.obj") + " --visual-out " + (dir / "xv.vtp").string() +
             " --report " + (dir / "xv.json").string());
  ASSERT_EQ(with_visual.code, 0) << with_visual.err;
  const auto v = nlohmann::json::parse(test::file_bytes(dir / "xv.json"));
  EXPECT_TRUE(v["visual_watertight"].get<bool>());
  EXPECT_NEAR(v["visual_volume_out"].get<double>(), v["visual_volume_in"].get<double>(),
              0.01 * v["visual_volume_in"].get<double>());
  EXPECT_GT(v["visual_triangles"].get<int>(), 0);
  EXPECT_TRUE(std::filesystem::exists(dir / "xv.vtp"));
  const CommandResult visual_with_subdivision = incise(
      common + "-o " + (dir / "s.vtu").string() + " --visual " + data("sofa/liver-smooth.obj"));
  EXPECT_EQ(visual_with_subdivision.code, 2);
  EXPECT_NE(visual_with_subdivision.err.find("xfem"), std::string::npos)
      << visual_with_subdivision.err;
}

}  // namespace
}  // namespace incise
