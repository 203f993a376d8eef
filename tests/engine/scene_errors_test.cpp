// Malformed scenes: each gives an error naming the file, the line and column of the offending text,
// and what was expected.

#include <gtest/gtest.h>

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
