// Malformed scenes: each gives an error naming the file, the line and column of the offending text,
// and what was expected.

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "volpar/engine/builders/obj_reader.hpp"
#include "volpar/engine/core/input_file.hpp"
#include "volpar/engine/scene/scene_build.hpp"
#include "volpar/engine/scene/scene_loader.hpp"

#include "tests/support/test_support.hpp"

namespace volpar {
namespace {

struct Location {
  int line = 0;
  int column = 0;
};

/// 1-based line and column of the first occurrence of `needle` at or after `from` in `text`.
Location locate(const std::string& text, const std::string& needle, std::size_t from = 0) {
  const std::size_t pos = text.find(needle, from);
  EXPECT_NE(pos, std::string::npos) << needle;
  Location l{1, 1};
  for (std::size_t i = 0; i < pos; ++i) {
    if (text[i] == '\n') {
      ++l.line;
      l.column = 1;
    } else {
      ++l.column;
    }
  }
  return l;
}

const std::string kBox = "    shape: {box: {size: [0.3, 0.3, 0.3]}}\n    fill: {radius: 0.05}\n";

struct Case {
  std::string name;
  std::string text;
  std::string at;       ///< the text the error must point at
  std::string message;  ///< expected part of the message
  std::size_t from = 0; ///< search `at` from this offset
};

Case make(std::string name, std::string text, std::string at, std::string message) {
  return {std::move(name), std::move(text), std::move(at), std::move(message)};
}

std::vector<Case> cases() {
  std::vector<Case> c;
  c.push_back(make("unknown top-level key", "dt: 0.01\nsteps: 10\ngravty: [0, 0, -9.81]\nbodies:\n  - name: a\n" + kBox,
                   "gravty", "unknown key 'gravty' in scene (did you mean 'gravity'?); expected one of:"));
  c.push_back(make("zero time step", "dt: 0\nsteps: 10\nbodies:\n  - name: a\n" + kBox, "0\n",
                   "expected a positive time step dt [s], got 0"));
  c.push_back(make("negative radius", "dt: 0.01\nsteps: 10\nbodies:\n  - shape: {sphere: {radius: 0.5}}\n    fill: {radius: -0.05}\n",
                   "-0.05", "expected a positive particle radius [m], got -0.05"));
  c.push_back(make("wrong type", "dt: 0.01\nsteps: ten\nbodies:\n  - name: a\n" + kBox, "ten",
                   "expected a number for steps, got 'ten'"));
  c.push_back(make("zero-length rotation axis",
                   "dt: 0.01\nsteps: 1\nbodies:\n  - name: a\n" + kBox + "    orientation: {axis: [0, 0, 0], angle_deg: 30}\n",
                   "[0, 0, 0]", "expected a non-zero rotation axis"));
  c.push_back(make("missing mesh file",
                   "dt: 0.01\nsteps: 1\nbodies:\n  - shape: {mesh: {file: nothere.obj}}\n    fill: {radius: 0.05}\n",
                   "nothere.obj", "cannot open mesh file 'nothere.obj'"));
  c.push_back(make("open mesh", "dt: 0.01\nsteps: 1\nbodies:\n  - name: lid\n    shape: {mesh: {file: ../tests/data/open_box.obj}}\n    fill: {radius: 0.1}\n",
                   "name: lid", "body 'lid': "));
  c.push_back(make("overlapping bodies",
                   "dt: 0.01\nsteps: 1\nbodies:\n  - name: a\n" + kBox + "  - name: b\n" + kBox + "    position: [0.2, 0, 0]\n",
                   "name: b", "bodies 'a' and 'b' overlap at start by 0.1 m"));
  c.push_back(make("steps and duration", "dt: 0.01\nsteps: 10\nduration: 1\nbodies:\n  - name: a\n" + kBox, "dt",
                   "expected exactly one of 'steps' or 'duration' [s] in scene"));
  c.push_back(make("missing bodies", "dt: 0.01\nsteps: 10\n", "dt", "missing key 'bodies' in scene"));
  c.push_back(make("unknown shape kind", "dt: 0.01\nsteps: 1\nbodies:\n  - shape: {cube: {size: 1}}\n    fill: {radius: 0.05}\n",
                   "cube", "unknown key 'cube' in shape"));
  c.push_back(make("restitution out of range",
                   "dt: 0.01\nsteps: 1\nmaterials:\n  rubber: {restitution: 1.5}\nbodies:\n  - name: a\n" + kBox, "1.5",
                   "expected restitution in [0, 1], got 1.5"));
  c.push_back(make("unknown material",
                   "dt: 0.01\nsteps: 1\nmaterials:\n  steel: {density: 7800}\nbodies:\n  - name: a\n    material: steal\n" + kBox,
                   "steal", "unknown material 'steal' (did you mean 'steel'?)"));
  c.push_back(make("vector of two", "dt: 0.01\nsteps: 1\nbodies:\n  - name: a\n" + kBox + "    position: [0, 0]\n", "[0, 0]",
                   "expected a list of 3 numbers [x, y, z] for position"));
  c.push_back(make("duplicate key", "dt: 0.01\nsteps: 1\ndt: 0.02\nbodies:\n  - name: a\n" + kBox, "dt: 0.02",
                   "duplicate key 'dt' in scene"));
  c.push_back(make("invalid YAML", "dt: 0.01\nsteps: 1\nbodies: [\n  {name: a\n", "", "invalid YAML"));
  c.push_back(make("unknown lattice", "dt: 0.01\nsteps: 1\nbodies:\n  - shape: {sphere: {radius: 0.5}}\n    fill: {radius: 0.05, lattice: fcc}\n",
                   "fcc", "unknown lattice 'fcc' (did you mean 'hcp'?); expected one of: cubic, hcp"));
  c.push_back(make("springs on a rigid body",
                   "dt: 0.01\nsteps: 1\nbodies:\n  - name: a\n" + kBox + "    connectors: {springs: {stiffness: 100}}\n",
                   "springs", "springs need 'kind: deformable'"));
  c.push_back(make("deformable without connectors",
                   "dt: 0.01\nsteps: 1\nbodies:\n  - name: jelly\n    kind: deformable\n" + kBox, "name: jelly",
                   "missing key 'connectors' in body 'jelly'"));
  c.push_back(make("body below a plane",
                   "dt: 0.01\nsteps: 1\nplanes:\n  - {normal: [0, 0, 1], offset: 0}\nbodies:\n  - name: sunk\n" + kBox,
                   "name: sunk", "body 'sunk' overlaps plane 0 (line 4) at start by 0.15 m"));
  c.push_back(make("absurd radius", "dt: 0.01\nsteps: 1\nbodies:\n  - name: dust\n    shape: {box: {size: [1, 1, 1]}}\n    fill: {radius: 1e-5}\n",
                   "name: dust", "would create about 1.25e+14 particles; expected at most 50000000"));
  c.push_back(make("non-finite number", "dt: 0.01\nsteps: 1\nbodies:\n  - name: a\n" + kBox + "    position: [0, 0, inf]\n",
                   "inf", "expected a finite number for position, got 'inf'"));
  c.push_back(make("repeat count zero",
                   "dt: 0.01\nsteps: 1\nbodies:\n  - name: a\n" + kBox + "    repeat: {count: [1, 0, 1], spacing: [1, 1, 1]}\n",
                   "0, 1]", "expected repeat count in [1, 1000000], got 0"));
  c.push_back(make("static with velocity",
                   "dt: 0.01\nsteps: 1\nbodies:\n  - name: floor\n    kind: static\n" + kBox + "    velocity: [1, 0, 0]\n",
                   "name: floor", "a static body cannot have a velocity"));
  c.push_back(make("radius and radii", "dt: 0.01\nsteps: 1\nbodies:\n  - shape:\n      particles: {positions: [[0, 0, 0]], radius: 0.1, radii: [0.1]}\n",
                   "{positions", "expected exactly one of 'radius' (all particles) or 'radii' (one per particle)"));
  c.push_back(make("reach too short", "dt: 0.01\nsteps: 1\nbodies:\n  - shape: {sphere: {radius: 0.5}}\n    fill: {radius: 0.05, reach: 0.9}\n",
                   "0.9", "expected reach in (1, 4] lattice spacings"));
  c.push_back(make("connector index out of range",
                   "dt: 0.01\nsteps: 1\nbodies:\n  - shape:\n      particles: {positions: [[0, 0, 0], [0.1, 0, 0]], radius: 0.05, connectors: [[0, 2]]}\n",
                   "2]]", "expected particle index in [0, 1], got 2"));
  c.push_back(make("pin on a rigid body",
                   "dt: 0.01\nsteps: 1\nbodies:\n  - name: a\n" + kBox + "    pin: {min: [0, 0, 0], max: [1, 1, 1]}\n", "pin:",
                   "only deformable bodies can have pinned particles"));
  c.push_back(make("pin holding nothing",
                   "dt: 0.01\nsteps: 1\nbodies:\n  - name: a\n    kind: deformable\n    connectors: {springs: {stiffness: 100}}\n" +
                       kBox + "    pin: [{min: [-1, -1, -1], max: [1, 1, 1]}, {min: [5, 5, 5], max: [6, 6, 6]}]\n",
                   "{min: [5", "this pin box holds no particle of the body"));
  c.push_back(make("pin max below min",
                   "dt: 0.01\nsteps: 1\nbodies:\n  - name: a\n    kind: deformable\n    connectors: {springs: {stiffness: 100}}\n" +
                       kBox + "    pin: {min: [0, 0, 0], max: [1, -1, 1]}\n",
                   "[1, -1, 1]", "expected pin max >= pin min in every coordinate"));
  c.push_back(make("strength on a static body",
                   "dt: 0.01\nsteps: 1\nbodies:\n  - name: a\n    kind: static\n" + kBox + "    connectors: {rods: {strength: 10}}\n",
                   "strength", "static bodies never break"));
  c.push_back(make("negative strain limit",
                   "dt: 0.01\nsteps: 1\nbodies:\n  - name: a\n    kind: deformable\n" + kBox +
                       "    connectors: {springs: {stiffness: 100, strain_limit: -0.1}}\n",
                   "-0.1", "expected a positive spring strain limit"));
  c.push_back(make("material rod strength zero",
                   "dt: 0.01\nsteps: 1\nmaterials:\n  chalk: {rod_strength: 0}\nbodies:\n  - name: a\n" + kBox, "0}",
                   "expected a positive rod strength"));
  c.push_back(make("shape normals on a particle list",
                   "dt: 0.01\nsteps: 1\nbodies:\n  - shape:\n      particles: {positions: [[0, 0, 0]], radius: 0.1}\n"
                   "    normals: shape\n",
                   "shape\n", "an explicit particle list has no solid to take normals from; expected 'normals: estimated'"));
  c.push_back(make("unknown body normals", "dt: 0.01\nsteps: 1\nbodies:\n  - name: a\n" + kBox + "    normals: estimate\n",
                   "estimate\n", "unknown normals 'estimate' (did you mean 'estimated'?); expected one of: shape, estimated"));
  c.push_back(make("unknown top-level normals", "dt: 0.01\nsteps: 1\nnormals: smooth\nbodies:\n  - name: a\n" + kBox,
                   "smooth", "unknown normals 'smooth'; expected one of: shape, estimated"));
  c.push_back(make("normals not a name", "dt: 0.01\nsteps: 1\nnormals: [shape]\nbodies:\n  - name: a\n" + kBox,
                   "[shape]", "expected a string for normals, got a list"));
  c.push_back(make("springs with neither stiffness nor modulus",
                   "dt: 0.01\nsteps: 1\nbodies:\n  - name: a\n    kind: deformable\n    connectors: {springs: {}}\n" + kBox,
                   "name: a", "springs need a 'stiffness' [N/m], or their material's 'youngs_modulus' [Pa]"));
  c.push_back(make("bonds on a deformable body",
                   "dt: 0.01\nsteps: 1\nbodies:\n  - name: a\n    kind: deformable\n    connectors: bonds\n" + kBox, "bonds\n",
                   "bonds join the particles of rigid bodies"));
  c.push_back(make("bonds without a modulus", "dt: 0.01\nsteps: 1\nbodies:\n  - name: a\n    connectors: bonds\n" + kBox,
                   "name: a", "bonds need their material's Young's modulus"));
  c.push_back(make("Poisson's ratio of a half",
                   "dt: 0.01\nsteps: 1\nmaterials:\n  jelly: {poisson_ratio: 0.5}\nbodies:\n  - name: a\n" + kBox, "0.5}",
                   "expected a Poisson's ratio in (-1, 0.5)"));
  c.push_back(make("bond radius above one",
                   "dt: 0.01\nsteps: 1\nmaterials:\n  rock: {youngs_modulus: 1.0e9}\nbodies:\n  - name: a\n    material: rock\n"
                   "    connectors: {bonds: {radius: 1.5}}\n" + kBox, "1.5}",
                   "expected a bond radius in (0, 1]"));
  c.push_back(make("glue naming no body",
                   "dt: 0.01\nsteps: 1\nmaterials:\n  rock: {youngs_modulus: 1.0e9}\nbodies:\n  - name: a\n    material: rock\n"
                   "    connectors: bonds\n" + kBox + "glue:\n  - {bodies: [a, b], material: rock}\n", "b]",
                   "glue 'glued0': no body named 'b'"));
  c.push_back(make("glue with bodies and pairs",
                   "dt: 0.01\nsteps: 1\nbodies:\n  - name: a\n" + kBox + "glue:\n  - {bodies: [a], pairs: [[a, a]]}\n", "{bodies",
                   "expected exactly one of 'bodies' (all their touching pairs) or 'pairs' in glue"));
  c.push_back(make("seed negative", "dt: 0.01\nsteps: 1\nseed: -1\nbodies:\n  - name: a\n" + kBox, "-1", "seed"));
  c.push_back(make("empty scene", "", "", "the scene is empty"));
  c.push_back(make("bodies not a list", "dt: 0.01\nsteps: 1\nbodies: {a: 1}\n", "{a: 1}", "expected a non-empty list of bodies"));
  return c;
}

TEST(SceneErrors, EachMalformedSceneNamesFileLineColumnAndExpectation) {
  const auto all = cases();
  ASSERT_GE(all.size(), 15u);
  for (const Case& c : all) {
    SCOPED_TRACE(c.name);
    auto desc = test::sceneFromString(c.text, "bad.yaml");
    Error error;
    if (desc.ok()) {
      auto built = buildScene(*desc);
      ASSERT_FALSE(built.ok()) << "scene was accepted";
      error = built.error();
    } else {
      error = desc.error();
    }
    EXPECT_EQ(error.file, test::sourcePath("scenes/bad.yaml"));
    EXPECT_NE(error.message.find(c.message), std::string::npos) << error.toString();
    if (c.at.empty()) {
      EXPECT_GE(error.line, 1) << error.toString();
      continue;
    }
    const Location expected = locate(c.text, c.at, c.from);
    EXPECT_EQ(error.line, expected.line) << error.toString();
    EXPECT_EQ(error.column, expected.column) << error.toString();
    // the printed form starts with file:line:column
    EXPECT_EQ(error.toString().rfind(error.file + ":" + std::to_string(expected.line) + ":" +
                                         std::to_string(expected.column) + ": ",
                                     0),
              0u);
  }
}

TEST(SceneErrors, OpenMeshErrorAlsoNamesTheMeshLine) {
  auto desc = test::sceneFromString(
      "dt: 0.01\nsteps: 1\nbodies:\n  - name: lid\n    shape: {mesh: {file: ../tests/data/open_box.obj}}\n    fill: {radius: 0.1}\n");
  ASSERT_TRUE(desc.ok()) << desc.error().toString();
  auto built = buildScene(*desc);
  ASSERT_FALSE(built.ok());
  EXPECT_NE(built.error().message.find("open_box.obj:"), std::string::npos) << built.error().message;
  EXPECT_NE(built.error().message.find("mesh is not closed"), std::string::npos) << built.error().message;
}

TEST(SceneErrors, DirectionsOfAnyFiniteSizeAreNormalisedNotLost) {
  // components whose squares overflow (or underflow) still give the direction they point in
  auto desc = test::sceneFromString(
      "dt: 0.01\nsteps: 1\nplanes:\n  - {normal: [0, 1e-300, 1e-300], offset: -5}\nbodies:\n"
      "  - name: q\n" + kBox + "    orientation: {quaternion: [1e300, 1e300, 0, 0]}\n"
      "  - name: a\n" + kBox + "    position: [3, 0, 0]\n    orientation: {axis: [1e308, 1e308, 0], angle: 1}\n");
  ASSERT_TRUE(desc.ok()) << desc.error().toString();
  const double h = std::sqrt(0.5);
  EXPECT_NEAR(desc->bodies[0].orientation.w(), h, 1e-15);
  EXPECT_NEAR(desc->bodies[0].orientation.x(), h, 1e-15);
  const Quat expected(Eigen::AngleAxisd(1.0, Vec3(h, h, 0.0)));
  EXPECT_LT(desc->bodies[1].orientation.angularDistance(expected), 1e-14);
  EXPECT_NEAR(desc->planes[0].normal.y(), h, 1e-15);
  EXPECT_NEAR(desc->planes[0].normal.z(), h, 1e-15);
}

TEST(SceneErrors, ValuesBeyondTheLimitsAreRefusedWhereGiven) {
  struct Bad {
    std::string text, message;
  };
  const std::vector<Bad> bad = {
      {"    position: [0, 0, 2e6]\n", "expected components of position of at most 1e+06 m"},
      {"    velocity: [1e300, 0, 0]\n", "expected components of velocity of at most 1e+06 m/s"},
      {"    angular_velocity: [0, 0, -1e7]\n", "of at most 1e+06 rad/s"},
  };
  for (const Bad& b : bad) {
    auto desc = test::sceneFromString("dt: 0.01\nsteps: 1\nbodies:\n  - name: a\n" + kBox + b.text);
    ASSERT_FALSE(desc.ok()) << b.text;
    EXPECT_EQ(desc.error().line, 7) << desc.error().toString();
    EXPECT_NE(desc.error().message.find(b.message), std::string::npos) << desc.error().toString();
  }
  auto big = test::sceneFromString("dt: 0.01\nsteps: 1\nbodies:\n  - name: a\n    shape: {box: {size: [3e6, 1, 1]}}\n"
                                   "    fill: {radius: 0.1}\n");
  ASSERT_FALSE(big.ok());
  EXPECT_NE(big.error().message.find("box size of at most 1e+06 m"), std::string::npos) << big.error().toString();
}

TEST(SceneErrors, DeepNestingIsRefusedBeforeParsing) {
  for (const std::string& text : {"a: " + std::string(5000, '[') + std::string(5000, ']') + "\n",
                                  [] {
                                    std::string t;
                                    for (int i = 0; i < 200; ++i) t += std::string(static_cast<std::size_t>(i), ' ') + "k:\n";
                                    return t;
                                  }(),
                                  "a:\n" + [] {
                                    std::string t;
                                    for (int i = 0; i < 100; ++i) t += "- ";
                                    return t + "x\n";
                                  }()}) {
    auto desc = test::sceneFromString(text);
    ASSERT_FALSE(desc.ok());
    EXPECT_NE(desc.error().message.find("nested deeper than 64 levels"), std::string::npos) << desc.error().toString();
    EXPECT_GE(desc.error().line, 1);
  }
  // a scene nested as scenes are is not affected: a list of lists of lists
  auto ok = test::sceneFromString("dt: 0.01\nsteps: 1\nbodies:\n  - name: a\n    shape: {particles: {positions: "
                                  "[[0, 0, 0], [0.1, 0, 0]], radius: 0.05}}\n");
  EXPECT_TRUE(ok.ok()) << ok.error().toString();
}

TEST(SceneErrors, MeshesOutsideTheScenesFolderAreRefusedUnlessAllowed) {
  namespace fs = std::filesystem;
  const std::string dir = test::tempDir();
  fs::create_directories(dir + "/scene/inner");
  fs::create_directories(dir + "/elsewhere");
  fs::copy_file(test::sourcePath("scenes/examples/meshes/l_shape.obj"), dir + "/elsewhere/l.obj");
  fs::copy_file(test::sourcePath("scenes/examples/meshes/l_shape.obj"), dir + "/scene/inner/l.obj");
  fs::create_symlink(dir + "/elsewhere/l.obj", dir + "/scene/link.obj");
  const auto load = [&](const std::string& file, const std::vector<std::string>& allowed) {
    LoadOptions options;
    options.allowedDirs = allowed;
    return parseScene("dt: 0.01\nsteps: 1\nbodies:\n  - shape: {mesh: {file: " + file + "}}\n    fill: {radius: 0.1}\n",
                      dir + "/scene/s.yaml", options);
  };
  EXPECT_TRUE(load("inner/l.obj", {}).ok());
  EXPECT_TRUE(load("inner/../inner/l.obj", {}).ok());
  for (const std::string& escape : {std::string("../elsewhere/l.obj"), std::string("link.obj"), dir + "/elsewhere/l.obj",
                                    std::string("../../../../../../etc/passwd")}) {
    auto refused = load(escape, {});
    ASSERT_FALSE(refused.ok()) << escape;
    EXPECT_NE(refused.error().message.find("outside the scene's folder"), std::string::npos) << refused.error().toString();
    EXPECT_EQ(refused.error().line, 4);
  }
  // a folder given on the command line
  EXPECT_TRUE(load("../elsewhere/l.obj", {dir + "/elsewhere"}).ok());
  EXPECT_TRUE(load("link.obj", {dir + "/elsewhere"}).ok());
  EXPECT_FALSE(load("../elsewhere/l.obj", {dir + "/scene/inner"}).ok());
}

TEST(SceneErrors, ScenesAndMeshesOverTheirSizeCapsOrNotFilesAreRefusedBeforeReading) {
  const std::string dir = test::tempDir();
  std::ofstream(dir + "/ten.txt") << "0123456789";
  auto small = readInputFile(dir + "/ten.txt", 9, "scene file");
  ASSERT_FALSE(small.ok());
  EXPECT_NE(small.error().message.find("scene file of 10 bytes; expected at most 9 bytes"), std::string::npos);
  EXPECT_TRUE(readInputFile(dir + "/ten.txt", 10, "scene file").ok());
  for (const std::string& notAFile : {std::string("/dev/zero"), dir}) {
    auto r = loadScene(notAFile);
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.error().message.find("not a regular file"), std::string::npos) << r.error().toString();
    auto m = readObj(notAFile);
    ASSERT_FALSE(m.ok());
    EXPECT_NE(m.error().message.find("not a regular file"), std::string::npos) << m.error().toString();
  }
}

TEST(SceneErrors, AScenePastTheMemoryLimitIsRefusedBeforeBuildingWithTheEstimate) {
  // a particle list with a reach that joins every particle to every other: ~n^2/2 springs
  std::string positions;
  for (int i = 0; i < 2000; ++i) positions += (i ? ", [" : "[") + std::to_string(0.1 * i) + ", 0, 0]";
  auto desc = test::sceneFromString("dt: 0.01\nsteps: 1\nbodies:\n  - name: small\n" + kBox +
                                    "  - name: web\n    shape: {particles: {positions: [" + positions +
                                    "], radius: 0.05, reach: 500}}\n    position: [0, 5, 0]\n");
  ASSERT_TRUE(desc.ok()) << desc.error().toString();
  const auto estimate = estimateScene(*desc);
  ASSERT_TRUE(estimate.ok());
  EXPECT_NEAR(estimate->connectors, 2000.0 * 1999.0 / 2.0 + 13.0 * 27.0, 0.05 * 2e6);
  BuildOptions options;
  options.memoryLimit = std::uint64_t{64} << 20;  // the web's ~2 million springs need ~130 MiB
  auto built = buildScene(*desc, options);
  ASSERT_FALSE(built.ok());
  EXPECT_EQ(built.error().line, 7) << built.error().toString();  // the body that needs the most
  EXPECT_NE(built.error().message.find("connectors"), std::string::npos) << built.error().toString();
  EXPECT_NE(built.error().message.find("the limit is 0.0625 GiB (--memory-limit)"), std::string::npos)
      << built.error().toString();
  options.memoryLimit = std::uint64_t{1} << 30;
  EXPECT_TRUE(buildScene(*desc, options).ok());
}

TEST(SceneErrors, IntendedOverlapIsAccepted) {
  auto desc = test::sceneFromString("dt: 0.01\nsteps: 1\nallow_initial_overlap: true\nbodies:\n  - name: a\n" + kBox +
                                    "  - name: b\n" + kBox + "    position: [0.2, 0, 0]\n");
  ASSERT_TRUE(desc.ok()) << desc.error().toString();
  auto built = buildScene(*desc);
  ASSERT_TRUE(built.ok()) << built.error().toString();
  EXPECT_EQ(built->world.bodies().size(), 2u);
}

TEST(SceneErrors, TouchingBodiesAreNotOverlapping) {
  // two 0.3 m boxes side by side: the facing particles touch exactly
  auto desc = test::sceneFromString("dt: 0.01\nsteps: 1\nbodies:\n  - name: a\n" + kBox + "    repeat: {count: [1, 1, 10], spacing: [0, 0, 0.3]}\n");
  ASSERT_TRUE(desc.ok()) << desc.error().toString();
  auto built = buildScene(*desc);
  ASSERT_TRUE(built.ok()) << built.error().toString();
  EXPECT_EQ(built->world.bodies().size(), 10u);
  EXPECT_EQ(built->world.bodies().info[3].name, "a[0,0,3]");
}

}  // namespace
}  // namespace volpar
