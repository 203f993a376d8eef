// Trajectory files: what is written reads back (through the HDF5 C API), the layout is chunked and
// compressed, and a run that is killed or interrupted leaves a readable file.

#include <gtest/gtest.h>
#include <hdf5.h>
#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <bit>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <thread>
#include <tuple>

#include "volpar/engine/io/h5md_reader.hpp"
#include "volpar/engine/io/h5md_writer.hpp"
#include "volpar/engine/io/xdmf_writer.hpp"
#include "volpar/engine/run_loop.hpp"
#include "tests/support/test_support.hpp"

namespace volpar {
namespace {

const char* kScene = R"(
name: tumble
dt: 0.005
steps: 40
output: {every: 10}
bodies:
  - name: crate
    shape: {box: {size: [0.3, 0.2, 0.1]}}
    fill: {radius: 0.05}
    velocity: [1, 0, 2]
    angular_velocity: [0, 3, 1]
  - name: ball
    shape: {sphere: {radius: 0.2}}
    fill: {radius: 0.05, lattice: hcp}
    position: [1, 0, 0]
)";

std::vector<double> readDoubles(hid_t file, const char* name) {
  const hid_t ds = H5Dopen2(file, name, H5P_DEFAULT);
  EXPECT_GE(ds, 0) << name;
  const hid_t space = H5Dget_space(ds);
  const hssize_t n = H5Sget_simple_extent_npoints(space);
  std::vector<double> out(static_cast<std::size_t>(n));
  EXPECT_GE(H5Dread(ds, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, out.data()), 0);
  H5Sclose(space);
  H5Dclose(ds);
  return out;
}

TEST(H5md, RoundTripOfEveryFrame) {
  auto desc = test::sceneFromString(kScene);
  ASSERT_TRUE(desc.ok()) << desc.error().toString();
  auto built = buildScene(*desc);
  ASSERT_TRUE(built.ok());
  World& world = built->world;

  // reference: the same scene stepped by hand
  auto reference = buildScene(*desc);
  const auto positions = [](const World& w) { return std::vector<Vec3>(w.particles().position.begin(), w.particles().position.end()); };
  std::vector<std::vector<Vec3>> expected{positions(reference->world)};
  std::vector<std::vector<Vec3>> expectedBodies{{reference->world.bodies().state[0].position, reference->world.bodies().state[1].position}};
  for (int i = 1; i <= 40; ++i) {
    ASSERT_EQ(reference->world.step(), StepStatus::Ok);
    if (i % 10 == 0) {
      expected.push_back(positions(reference->world));
      expectedBodies.push_back({reference->world.bodies().state[0].position, reference->world.bodies().state[1].position});
    }
  }

  const std::string path = test::tempDir() + "/tumble.h5";
  TrajectoryMeta meta{desc->name, "inline.yaml", desc->text, {}, 10, 40};
  RunOptions options;
  options.output = path;
  options.steps = 40;
  options.every = 10;
  auto summary = runWorld(world, meta, options);
  ASSERT_TRUE(summary.ok()) << summary.error().toString();
  EXPECT_EQ(summary->frames, 5u);

  auto reader = H5mdReader::open(path);
  ASSERT_TRUE(reader.ok()) << reader.error().toString();
  auto s = (*reader)->summary();
  ASSERT_TRUE(s.ok()) << s.error().toString();
  EXPECT_EQ(s->creatorName, "volpar");
  EXPECT_EQ(s->sceneName, "tumble");
  EXPECT_EQ(s->sceneText, desc->text);
  EXPECT_EQ(s->frames, 5u);
  EXPECT_EQ(s->particles, world.particles().size());
  EXPECT_EQ(s->bodyNames, (std::vector<std::string>{"crate", "ball"}));
  EXPECT_EQ(s->step, (std::vector<std::int64_t>{0, 10, 20, 30, 40}));
  for (std::size_t t = 0; t < 5; ++t) {
    EXPECT_DOUBLE_EQ(s->time[t], static_cast<double>(s->step[t]) * 0.005);
    auto pos = (*reader)->positions(t);
    ASSERT_TRUE(pos.ok());
    EXPECT_EQ(pos.value(), expected[t]) << "frame " << t;  // bit for bit
    auto bodies = (*reader)->bodyPositions(t);
    ASSERT_TRUE(bodies.ok());
    EXPECT_EQ(bodies.value(), expectedBodies[t]);
  }
  // the last frame's orientation is the shape frame's
  auto q = (*reader)->bodyOrientations(4);
  ASSERT_TRUE(q.ok());
  EXPECT_LT(q.value()[0].angularDistance(world.bodies().shapeOrientation(BodyId(0u))), 1e-15);
  // energies as observables
  EXPECT_DOUBLE_EQ(s->kinetic.back(), world.energy().kinetic);
  EXPECT_DOUBLE_EQ(s->total.front(), summary->energyStart.total());

  // the layout through the plain C API: chunked and compressed, radius and mass as fixed datasets
  const hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  ASSERT_GE(f, 0);
  const hid_t ds = H5Dopen2(f, "/particles/all/position/value", H5P_DEFAULT);
  const hid_t dcpl = H5Dget_create_plist(ds);
  EXPECT_EQ(H5Pget_layout(dcpl), H5D_CHUNKED);
  // compressed (shuffle + deflate) only where one frame fills its chunks: a chunk rewritten frame after frame
  // stays uncompressed, in place, so that a kill mid-frame cannot spoil the frames before it
  hsize_t chunk[3] = {0, 0, 0};
  ASSERT_EQ(H5Pget_chunk(dcpl, 3, chunk), 3);
  if (chunk[0] == 1) {
    EXPECT_GE(H5Pget_nfilters(dcpl), 2);
  } else {
    EXPECT_EQ(H5Pget_nfilters(dcpl), 0);
  }
  H5Pclose(dcpl);
  H5Dclose(ds);
  const std::vector<double> radius = readDoubles(f, "/particles/all/radius");
  EXPECT_EQ(radius, std::vector<double>(world.particles().radius.begin(), world.particles().radius.end()));
  const std::vector<double> mass = readDoubles(f, "/particles/bodies/mass");
  EXPECT_DOUBLE_EQ(mass[0], world.bodies().info[0].mass);
  H5Fclose(f);

  // the sidecar references the file and every frame
  std::ifstream x(sidecarPath(path));
  ASSERT_TRUE(x.good());
  const std::string xml((std::istreambuf_iterator<char>(x)), std::istreambuf_iterator<char>());
  EXPECT_NE(xml.find("tumble.h5:/particles/all/position/value"), std::string::npos);
  EXPECT_NE(xml.find("<Grid Name=\"step_40\""), std::string::npos);
  EXPECT_NE(xml.find("Dimensions=\"5 " + std::to_string(world.particles().size()) + " 3\""), std::string::npos);
}

/// A whole dataset (any rank) in the memory type `type`.
template <class T>
std::vector<T> readAll(hid_t file, const char* name, hid_t type) {
  const hid_t ds = H5Dopen2(file, name, H5P_DEFAULT);
  EXPECT_GE(ds, 0) << name;
  const hid_t space = H5Dget_space(ds);
  std::vector<T> out(static_cast<std::size_t>(H5Sget_simple_extent_npoints(space)));
  if (!out.empty()) {
    EXPECT_GE(H5Dread(ds, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, out.data()), 0) << name;
  }
  H5Sclose(space);
  H5Dclose(ds);
  return out;
}

/// The file type of a dataset: class, size in bytes, signedness (integers).
std::tuple<H5T_class_t, std::size_t, H5T_sign_t> fileTypeOf(hid_t file, const char* name) {
  const hid_t ds = H5Dopen2(file, name, H5P_DEFAULT);
  const hid_t type = H5Dget_type(ds);
  const H5T_class_t c = H5Tget_class(type);
  auto out = std::make_tuple(c, H5Tget_size(type), c == H5T_INTEGER ? H5Tget_sign(type) : H5T_SGN_ERROR);
  H5Tclose(type);
  H5Dclose(ds);
  return out;
}

/// An attribute holding an array of variable-length strings.
std::vector<std::string> readStringsAttr(hid_t file, const char* object, const char* name) {
  const hid_t attr = H5Aopen_by_name(file, object, name, H5P_DEFAULT, H5P_DEFAULT);
  EXPECT_GE(attr, 0) << object << "@" << name;
  const hid_t space = H5Aget_space(attr);
  std::vector<char*> ptrs(static_cast<std::size_t>(H5Sget_simple_extent_npoints(space)), nullptr);
  const hid_t mem = H5Tcopy(H5T_C_S1);
  H5Tset_size(mem, H5T_VARIABLE);
  H5Tset_cset(mem, H5T_CSET_UTF8);
  EXPECT_GE(H5Aread(attr, mem, ptrs.data()), 0);
  std::vector<std::string> out;
  for (char* p : ptrs) {
    out.emplace_back(p ? p : "");
    H5free_memory(p);
  }
  H5Tclose(mem);
  H5Sclose(space);
  H5Aclose(attr);
  return out;
}

bool sameBits(double a, double b) { return std::bit_cast<std::uint64_t>(a) == std::bit_cast<std::uint64_t>(b); }

TEST(H5md, PatchRecordsOfEveryFrameReadBackBitForBit) {
  // bodies of every builder flying through each other, a static slab and two planes (scenes/regression)
  auto desc = loadScene(test::sourcePath("scenes/regression/crossing.yaml"));
  ASSERT_TRUE(desc.ok()) << desc.error().toString();
  auto built = buildScene(*desc);
  ASSERT_TRUE(built.ok()) << built.error().toString();
  World& world = built->world;

  // write a frame every 6 steps and keep what the narrow phase had at each
  constexpr int kSteps = 360, kEvery = 6;
  const std::string path = test::tempDir() + "/patches.h5";
  TrajectoryMeta meta{desc->name, "crossing.yaml", desc->text, {}, kEvery, kSteps};
  auto writer = H5mdWriter::create(path, world, meta);
  ASSERT_TRUE(writer.ok()) << writer.error().toString();
  std::vector<LargeVector<ContactPatch>> expected;
  std::vector<std::size_t> narrowPhaseContacts;
  const auto write = [&] {
    ASSERT_TRUE((*writer)->writeFrame(world).ok());
    expected.push_back(world.patches().patches);
    narrowPhaseContacts.push_back(world.patches().contacts.size());
    EXPECT_EQ(world.patches().contacts.size(), world.contacts().contacts.size());
  };
  write();
  for (int i = 1; i <= kSteps; ++i) {
    ASSERT_EQ(world.step(), StepStatus::Ok);
    if (i % kEvery == 0) write();
  }
  ASSERT_TRUE((*writer)->writeSidecar((*writer)->path()).ok());
  ASSERT_TRUE((*writer)->close().ok());
  const std::size_t frames = expected.size();
  ASSERT_EQ(frames, static_cast<std::size_t>(kSteps / kEvery + 1));

  // the run must exercise what is checked: frames without patches; plane, body-pair and self-contact
  // patches (the scene's geometry). Unvalidated and look-ahead patches depend on the narrow phase of the
  // day: their flags are compared whatever they are, and their absence is only reported.
  std::size_t total = 0, emptyFrames = 0, planePatches = 0, selfPatches = 0, pairPatches = 0, unvalidated = 0,
              lookAheads = 0;
  for (const auto& frame : expected) {
    total += frame.size();
    emptyFrames += frame.empty() ? 1 : 0;
    for (const ContactPatch& p : frame) {
      (p.plane.valid() ? planePatches : p.a == p.b ? selfPatches : pairPatches) += 1;
      unvalidated += p.validated ? 0 : 1;
      lookAheads += p.lookAhead ? 1 : 0;
    }
  }
  EXPECT_GT(emptyFrames, 0u);
  EXPECT_GT(planePatches, 0u);
  EXPECT_GT(selfPatches, 0u);
  EXPECT_GT(pairPatches, 0u);
  if (unvalidated == 0 || unvalidated == total || lookAheads == 0 || lookAheads == total)
    std::printf("note: %zu of %zu patches unvalidated, %zu decided by a look-ahead: the flags are not exercised "
                "both ways\n", unvalidated, total, lookAheads);

  const hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  ASSERT_GE(f, 0);
  const auto offset = readAll<std::int64_t>(f, "/patches/offset", H5T_NATIVE_INT64);
  const auto count = readAll<std::int64_t>(f, "/patches/count", H5T_NATIVE_INT64);
  const auto bodyA = readAll<std::int32_t>(f, "/patches/body_a", H5T_NATIVE_INT32);
  const auto bodyB = readAll<std::int32_t>(f, "/patches/body_b", H5T_NATIVE_INT32);
  const auto plane = readAll<std::int32_t>(f, "/patches/plane", H5T_NATIVE_INT32);
  const auto planeCase = readAll<std::int32_t>(f, "/patches/case", H5T_NATIVE_INT32);
  const auto source = readAll<std::int32_t>(f, "/patches/source", H5T_NATIVE_INT32);
  const auto point = readAll<double>(f, "/patches/point", H5T_NATIVE_DOUBLE);
  const auto normal = readAll<double>(f, "/patches/normal", H5T_NATIVE_DOUBLE);
  const auto depth = readAll<double>(f, "/patches/depth", H5T_NATIVE_DOUBLE);
  const auto validated = readAll<std::int8_t>(f, "/patches/validated", H5T_NATIVE_INT8);
  const auto lookAhead = readAll<std::int8_t>(f, "/patches/look_ahead", H5T_NATIVE_INT8);
  const auto lookAheadCase = readAll<std::int32_t>(f, "/patches/look_ahead_case", H5T_NATIVE_INT32);
  const auto contacts = readAll<std::int32_t>(f, "/patches/contacts", H5T_NATIVE_INT32);
  const auto step = readAll<std::int64_t>(f, "/patches/step", H5T_NATIVE_INT64);
  const auto time = readAll<double>(f, "/patches/time", H5T_NATIVE_DOUBLE);
  ASSERT_EQ(offset.size(), frames);
  ASSERT_EQ(count.size(), frames);
  for (const std::size_t n : {bodyA.size(), bodyB.size(), plane.size(), planeCase.size(), source.size(), depth.size(),
                              validated.size(), lookAhead.size(), lookAheadCase.size(), contacts.size()})
    ASSERT_EQ(n, total);
  ASSERT_EQ(point.size(), 3 * total);
  ASSERT_EQ(normal.size(), 3 * total);
  // the frames' clock is the particles' (hard links)
  EXPECT_EQ(step, readAll<std::int64_t>(f, "/particles/all/position/step", H5T_NATIVE_INT64));
  EXPECT_EQ(time, readAll<double>(f, "/particles/all/position/time", H5T_NATIVE_DOUBLE));
  for (const char* link : {"/patches/step", "/patches/time"}) {
    H5L_info_t info;
    ASSERT_GE(H5Lget_info(f, link, &info, H5P_DEFAULT), 0);
    EXPECT_EQ(info.type, H5L_TYPE_HARD) << link;
  }

  std::int64_t row = 0;
  for (std::size_t t = 0; t < frames; ++t) {
    SCOPED_TRACE("frame " + std::to_string(t));
    ASSERT_EQ(offset[t], row);
    ASSERT_EQ(count[t], static_cast<std::int64_t>(expected[t].size()));
    std::int64_t frameContacts = 0;
    for (const ContactPatch& p : expected[t]) {
      const auto i = static_cast<std::size_t>(row++);
      EXPECT_EQ(bodyA[i], static_cast<std::int32_t>(p.a.value));
      EXPECT_EQ(bodyB[i], p.b.valid() ? static_cast<std::int32_t>(p.b.value) : -1);
      EXPECT_EQ(plane[i], p.plane.valid() ? static_cast<std::int32_t>(p.plane.value) : -1);
      EXPECT_EQ(planeCase[i], static_cast<std::int32_t>(p.planeCase));
      EXPECT_EQ(source[i], static_cast<std::int32_t>(p.source));
      for (std::size_t k = 0; k < 3; ++k) {
        EXPECT_TRUE(sameBits(point[3 * i + k], p.point[static_cast<Eigen::Index>(k)])) << "point of patch " << i;
        EXPECT_TRUE(sameBits(normal[3 * i + k], p.normal[static_cast<Eigen::Index>(k)])) << "normal of patch " << i;
      }
      EXPECT_TRUE(sameBits(depth[i], p.depth)) << "depth of patch " << i;
      EXPECT_EQ(validated[i], p.validated ? 1 : 0);
      EXPECT_EQ(lookAhead[i], p.lookAhead ? 1 : 0);
      EXPECT_EQ(lookAheadCase[i], p.lookAhead ? static_cast<std::int32_t>(p.lookAheadCase) : -1);
      EXPECT_EQ(contacts[i], static_cast<std::int32_t>(p.count));
      frameContacts += contacts[i];
    }
    // every contact the narrow phase had (touching and speculative) is in exactly one patch
    EXPECT_EQ(frameContacts, static_cast<std::int64_t>(narrowPhaseContacts[t]));
  }

  // types: int32 indices, int8 flags, float64 vectors; the enums' names as attributes, in enum order
  EXPECT_EQ(fileTypeOf(f, "/patches/body_a"), std::make_tuple(H5T_INTEGER, std::size_t{4}, H5T_SGN_2));
  EXPECT_EQ(fileTypeOf(f, "/patches/validated"), std::make_tuple(H5T_INTEGER, std::size_t{1}, H5T_SGN_2));
  EXPECT_EQ(fileTypeOf(f, "/patches/look_ahead"), std::make_tuple(H5T_INTEGER, std::size_t{1}, H5T_SGN_2));
  EXPECT_EQ(fileTypeOf(f, "/patches/look_ahead_case"), std::make_tuple(H5T_INTEGER, std::size_t{4}, H5T_SGN_2));
  EXPECT_EQ(fileTypeOf(f, "/patches/normal"), std::make_tuple(H5T_FLOAT, std::size_t{8}, H5T_SGN_ERROR));
  std::vector<std::string> caseNames, sourceNames;
  for (std::size_t k = 0; k < kPlaneCaseCount; ++k) caseNames.emplace_back(planeCaseName(static_cast<PlaneCase>(k)));
  for (std::size_t k = 0; k < kNormalSourceCount; ++k)
    sourceNames.emplace_back(normalSourceName(static_cast<NormalSource>(k)));
  EXPECT_EQ(readStringsAttr(f, "/patches/case", "case_names"), caseNames);
  EXPECT_EQ(readStringsAttr(f, "/patches/look_ahead_case", "case_names"), caseNames);
  EXPECT_EQ(readStringsAttr(f, "/patches/source", "source_names"), sourceNames);
  H5Fclose(f);

  // the sidecar: a patch grid for each frame with patches (and none for the others)
  std::ifstream x(sidecarPath(path));
  const std::string xml((std::istreambuf_iterator<char>(x)), std::istreambuf_iterator<char>());
  for (std::size_t t = 0; t < frames; ++t) {
    const std::string grid = "<Grid Name=\"patches_step_" + std::to_string(kEvery * t) + "\"";
    EXPECT_EQ(xml.find(grid) != std::string::npos, !expected[t].empty()) << grid;
  }
}

// A trajectory whose name holds XML's special characters gets a sidecar that is still well-formed XML: the
// name is written with entities wherever the sidecar refers to the file.
TEST(H5md, SidecarEscapesTheFileName) {
  XdmfFrames frames;
  frames.h5Path = test::tempDir() + "/a\"&<>'b.h5";
  frames.particles = 2;
  frames.time = {0.0, 0.5};
  frames.step = {0, 50};
  ASSERT_TRUE(writeXdmf(frames).ok());
  std::ifstream in(sidecarPath(frames.h5Path));
  const std::string xml((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(xml.find(">a&quot;&amp;&lt;&gt;&apos;b.h5:/particles/all/position/value<"), std::string::npos) << xml;
  EXPECT_EQ(xml.find("a\"&<>'b"), std::string::npos);
  EXPECT_EQ(xmlEscaped("x<y&z"), "x&lt;y&amp;z");
}

TEST(H5md, SidecarSkipsThePatchGridOfFramesWithoutPatches) {
  XdmfFrames frames;
  frames.h5Path = test::tempDir() + "/run.h5";
  frames.particles = 4;
  frames.time = {0.0, 0.5, 1.0, 1.5};
  frames.step = {0, 50, 100, 150};
  frames.patchOffset = {0, 0, 3, 3};
  frames.patchCount = {0, 3, 0, 2};
  ASSERT_TRUE(writeXdmf(frames).ok());
  std::ifstream in(sidecarPath(frames.h5Path));
  const std::string xml((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  // the particles' collection is unchanged: every frame
  for (const char* grid : {"<Grid Name=\"step_0\"", "<Grid Name=\"step_50\"", "<Grid Name=\"step_100\"",
                           "<Grid Name=\"step_150\""})
    EXPECT_NE(xml.find(grid), std::string::npos) << grid;
  // patches: frames 1 and 3 only, rows 0..2 and 3..4 of the 5
  EXPECT_NE(xml.find("<Grid Name=\"patches\" GridType=\"Collection\" CollectionType=\"Temporal\">"), std::string::npos);
  EXPECT_EQ(xml.find("patches_step_0\""), std::string::npos);
  EXPECT_EQ(xml.find("patches_step_100\""), std::string::npos);
  const std::size_t one = xml.find("<Grid Name=\"patches_step_50\"");
  const std::size_t three = xml.find("<Grid Name=\"patches_step_150\"");
  ASSERT_NE(one, std::string::npos);
  ASSERT_NE(three, std::string::npos);
  EXPECT_NE(xml.find("NumberOfElements=\"3\"", one), std::string::npos);
  EXPECT_NE(xml.find(">0 0  1 1  3 3</DataItem>", one), std::string::npos);
  EXPECT_NE(xml.find(">3 0  1 1  2 3</DataItem>", three), std::string::npos);
  EXPECT_NE(xml.find(">3 1 2</DataItem>", three), std::string::npos);
  EXPECT_NE(xml.find("Dimensions=\"5 3\" NumberType=\"Float\" Precision=\"8\" Format=\"HDF\">run.h5:/patches/normal"),
            std::string::npos);
  // no empty HyperSlab anywhere (XDMF2 cannot allocate one); tags balanced
  EXPECT_EQ(xml.find("Dimensions=\"0"), std::string::npos);
  const auto occurrences = [&](const std::string& s) {
    std::size_t n = 0;
    for (std::size_t at = xml.find(s); at != std::string::npos; at = xml.find(s, at + 1)) ++n;
    return n;
  };
  EXPECT_EQ(occurrences("<Grid "), occurrences("</Grid>"));
  EXPECT_EQ(occurrences("<DataItem "), occurrences("</DataItem>"));
  EXPECT_EQ(occurrences("<Attribute "), occurrences("</Attribute>"));
}

/// Starts `volpar run` on a long scene with extra arguments; after `waitMs` (if > 0) sends `signal`.
/// Returns the wait status.
int runAndSignal(const std::string& scene, const std::string& out, const std::vector<std::string>& extra, int signal,
                 int waitMs) {
  const pid_t pid = fork();
  if (pid == 0) {
    const int devnull = ::open("/dev/null", O_WRONLY);
    dup2(devnull, STDOUT_FILENO);
    dup2(devnull, STDERR_FILENO);
    std::vector<std::string> args{"volpar", "run", scene, "-o", out};
    args.insert(args.end(), extra.begin(), extra.end());
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    execv(test::volparBinary().c_str(), argv.data());
    _exit(127);
  }
  if (waitMs > 0) {
    // the wait counts from when the run has begun writing (its partial file is there), not from the fork: a busy
    // machine can take longer than the wait itself to start the process
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    while (!std::filesystem::exists(partialPath(out)) && std::chrono::steady_clock::now() < deadline) {
      int early = 0;
      if (waitpid(pid, &early, WNOHANG) == pid) return early;  // ended before it wrote anything
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(waitMs));
    kill(pid, signal);
  }
  int status = 0;
  waitpid(pid, &status, 0);
  return status;
}

std::string writeLongScene(const std::string& dir) {
  const std::string scene = dir + "/long.yaml";
  std::ofstream(scene) << R"(
dt: 0.001
steps: 100000000
output: {every: 20}
bodies:
  - shape: {box: {size: [1, 1, 1]}}
    fill: {radius: 0.05}
    angular_velocity: [0.1, 2, 0.1]
)";
  return scene;
}

void expectReadable(const std::string& path) {
  auto reader = H5mdReader::open(path);
  ASSERT_TRUE(reader.ok()) << reader.error().toString();
  auto s = (*reader)->summary();
  ASSERT_TRUE(s.ok()) << s.error().toString();
  ASSERT_GE(s->frames, 2u);
  // frames every 20 steps; an interrupted run adds its final state
  for (std::size_t t = 1; t < s->frames; ++t) {
    EXPECT_GT(s->step[t], s->step[t - 1]);
    if (t + 1 < s->frames) {
      EXPECT_EQ(s->step[t] % 20, 0);
    }
  }
  auto last = (*reader)->positions(s->frames - 1);
  ASSERT_TRUE(last.ok()) << last.error().toString();
  for (const Vec3& p : last.value()) ASSERT_TRUE(p.allFinite());
}

TEST(H5md, KilledRunKeepsEveryFrameWrittenBeforeTheKill) {
  // the process sends itself SIGKILL (no cleanup at all) right after its 3rd, 17th or 40th frame
  const std::string dir = test::tempDir();
  const std::string scene = writeLongScene(dir);
  for (const int frames : {3, 17, 40}) {
    const std::string out = dir + "/killed" + std::to_string(frames) + ".h5";
    const int status = runAndSignal(scene, out, {"--kill-after-frames", std::to_string(frames)}, 0, 0);
    ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL);
    // the run never finished: the file keeps its partial name, and nothing takes the output's name
    EXPECT_FALSE(std::filesystem::exists(out));
    expectReadable(partialPath(out));
    auto reader = H5mdReader::open(partialPath(out));
    ASSERT_TRUE(reader.ok());
    EXPECT_EQ((*reader)->summary()->frames, static_cast<std::size_t>(frames));
  }
}

TEST(H5md, KilledRunLosesOnlyTheFramesAfterItsLastFlush) {
  // frames are flushed and counted every --flush-every seconds, and the first at once
  const std::string dir = test::tempDir();
  const std::string scene = writeLongScene(dir);
  const auto completeFrames = [&](const std::string& flushEvery) {
    const std::string out = dir + "/flush" + flushEvery + ".h5";
    const int status = runAndSignal(scene, out, {"--flush-every", flushEvery}, SIGKILL, 1500);
    EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL);
    auto reader = H5mdReader::open(partialPath(out));
    EXPECT_TRUE(reader.ok());
    if (!reader.ok()) return std::size_t{0};
    auto s = (*reader)->summary();
    EXPECT_TRUE(s.ok());
    return s.ok() ? s->frames : std::size_t{0};
  };
  // a long interval: the kill comes before the second flush, and only the first frame counts
  EXPECT_EQ(completeFrames("1000"), 1u);
  // a short one: flushes during the run
  EXPECT_GE(completeFrames("0.2"), 2u);
}

TEST(H5md, TerminatedRunClosesTheFileCleanly) {
  const std::string dir = test::tempDir();
  const std::string out = dir + "/terminated.h5";
  const int status = runAndSignal(writeLongScene(dir), out, {}, SIGTERM, 500);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 130);
  EXPECT_FALSE(std::filesystem::exists(out));
  expectReadable(partialPath(out));
}

TEST(H5md, InterruptedRunClosesTheFileWithItsLastFrame) {
  const std::string dir = test::tempDir();
  const std::string out = dir + "/interrupted.h5";
  const int status = runAndSignal(writeLongScene(dir), out, {}, SIGINT, 700);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 130);
  expectReadable(partialPath(out));
  EXPECT_EQ(partialPath(out), dir + "/interrupted.partial.h5");
  EXPECT_TRUE(std::filesystem::exists(sidecarPath(partialPath(out))));
  EXPECT_FALSE(std::filesystem::exists(sidecarPath(out)));
}

}  // namespace
}  // namespace volpar
