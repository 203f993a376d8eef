// OBJ parsing and closed-mesh validation: errors name the line (and column) of the offending statement.

#include <gtest/gtest.h>

#include "volpar/engine/builders/obj_reader.hpp"

namespace volpar {
namespace {

const char* kCube = R"(# unit cube
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 0 0 1
v 1 0 1
v 1 1 1
v 0 1 1
f 1 4 3 2
f 5 6 7 8
f 1 2 6 5
f 2 3 7 6
f 3 4 8 7
f 4 1 5 8
)";

TEST(ObjReader, CubeIsSolidWithUnitVolume) {
  auto m = parseObj(kCube, "cube.obj");
  ASSERT_TRUE(m.ok()) << m.error().toString();
  EXPECT_EQ(m->vertices.size(), 8u);
  EXPECT_EQ(m->triangles.size(), 12u);
  ASSERT_TRUE(m->makeSolid().ok());
  EXPECT_NEAR(m->volume(), 1.0, 1e-12);
  EXPECT_TRUE(m->contains(Vec3(0.5, 0.5, 0.5)));
  EXPECT_TRUE(m->contains(Vec3(0.01, 0.99, 0.5)));
  EXPECT_FALSE(m->contains(Vec3(1.01, 0.5, 0.5)));
  EXPECT_NEAR(m->distance(Vec3(0.5, 0.5, 0.2)), 0.2, 1e-12);
}

TEST(ObjReader, InsideOutMeshIsTurnedAround) {
  std::string text = kCube;
  // reverse every face
  text.replace(text.find("f 1 4 3 2"), 9, "f 2 3 4 1");
  text.replace(text.find("f 5 6 7 8"), 9, "f 8 7 6 5");
  text.replace(text.find("f 1 2 6 5"), 9, "f 5 6 2 1");
  text.replace(text.find("f 2 3 7 6"), 9, "f 6 7 3 2");
  text.replace(text.find("f 3 4 8 7"), 9, "f 7 8 4 3");
  text.replace(text.find("f 4 1 5 8"), 9, "f 8 5 1 4");
  auto m = parseObj(text, "cube.obj");
  ASSERT_TRUE(m.ok());
  EXPECT_LT(m->volume(), 0.0);
  ASSERT_TRUE(m->makeSolid().ok());
  EXPECT_NEAR(m->volume(), 1.0, 1e-12);
  EXPECT_TRUE(m->contains(Vec3(0.5, 0.5, 0.5)));
}

TEST(ObjReader, WeldsDuplicateVerticesAndHandlesSlashesAndNegativeIndices) {
  const char* text = R"(v 0 0 0
v 1 0 0
v 0 1 0
v 0 0 1
vn 0 0 1
f 1//1 3//1 2//1
f 1/1/1 2/1/1 4/1/1
v 0 0 0
f -1 4 3
f 2 3 4
)";
  auto m = parseObj(text, "tet.obj");
  ASSERT_TRUE(m.ok()) << m.error().toString();
  EXPECT_EQ(m->vertices.size(), 4u);  // the fifth vertex repeats the first
  ASSERT_TRUE(m->makeSolid().ok()) << m->makeSolid().error().toString();
  EXPECT_NEAR(m->volume(), 1.0 / 6.0, 1e-12);
}

TEST(ObjReader, OpenMeshIsRejectedWithTheLineOfAnOpenEdge) {
  std::string text = kCube;
  text.erase(text.find("f 4 1 5 8"));  // drop the last face (line 15)
  auto m = parseObj(text, "open.obj");
  ASSERT_TRUE(m.ok());
  const Status s = m->makeSolid();
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().file, "open.obj");
  EXPECT_GT(s.error().line, 9);
  EXPECT_NE(s.error().message.find("mesh is not closed"), std::string::npos) << s.error().message;
}

TEST(ObjReader, InconsistentOrientationIsRejected) {
  std::string text = kCube;
  text.replace(text.find("f 2 3 7 6"), 9, "f 6 7 3 2");  // one face flipped (line 13)
  auto m = parseObj(text, "flipped.obj");
  ASSERT_TRUE(m.ok());
  const Status s = m->makeSolid();
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("not consistently oriented"), std::string::npos) << s.error().message;
}

TEST(ObjReader, SyntaxErrorsGiveLineAndColumn) {
  struct Case {
    const char* text;
    int line, column;
    const char* message;
  };
  const Case cases[] = {
      {"v 0 0 0\nv 1 x 0\n", 2, 5, "expected a finite number for a vertex coordinate"},
      {"v 0 0 0\nv 1 2e6 0\n", 2, 5, "vertex coordinate (times the scale 1.000000) beyond 1000000 m"},
      {"v 0 0\n", 1, 1, "expected a vertex 'v x y z' with 3 coordinates"},
      {"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n", 4, 7, "vertex index 9 is out of range; the file has 3 vertices"},
      {"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n", 4, 7, "expected a vertex index"},
      {"v 0 0 0\n  curv 1 2\n", 2, 3, "not an OBJ statement; expected v or f"},
      // a file that is not a mesh: located, its content never repeated
      {"root:x:0:0:secret:/root:/bin/bash\n", 1, 1, "not an OBJ statement"},
      {"v 0 0 0\nf 1 1\n", 2, 1, "expected a face with at least 3 vertices"},
      {"v 0 0 0\n", 0, 0, "no faces found"},
  };
  for (const Case& c : cases) {
    auto m = parseObj(c.text, "bad.obj");
    ASSERT_FALSE(m.ok()) << c.text;
    EXPECT_EQ(m.error().line, c.line) << c.text;
    EXPECT_EQ(m.error().column, c.column) << c.text;
    EXPECT_NE(m.error().message.find(c.message), std::string::npos) << m.error().message;
    EXPECT_EQ(m.error().message.find("secret"), std::string::npos) << m.error().message;
  }
}

TEST(ObjReader, DegenerateTriangleIsRejected) {
  auto m = parseObj("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n", "flat.obj");
  ASSERT_TRUE(m.ok());
  const Status s = m->makeSolid();
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().line, 4);
  EXPECT_NE(s.error().message.find("degenerate triangle"), std::string::npos);
}

TEST(ObjReader, MissingFileIsAnError) {
  auto m = readObj("/nonexistent/mesh.obj");
  ASSERT_FALSE(m.ok());
  EXPECT_NE(m.error().message.find("cannot open"), std::string::npos);
}

}  // namespace
}  // namespace volpar
