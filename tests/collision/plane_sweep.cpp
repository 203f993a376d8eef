#include "tests/collision/plane_sweep.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <numbers>
#include <limits>
#include <random>

#include "volpar/collision/reference/fcl_adapter.hpp"
#include "volpar/engine/builders/shapes.hpp"

namespace volpar::test {

namespace {

SweepShape make(const char* name, SourceShape source, const SolidShape& solid, Lattice lattice, double r, bool estimated) {
  auto c = fillShape(solid, {lattice, r});
  EXPECT_TRUE(c.ok()) << name;
  SweepShape s;
  s.name = name;
  s.source = std::move(source);
  if (c.ok()) s.cloud = std::move(c.value());
  if (estimated) useEstimatedNormals(s.cloud);
  return s;
}

Quat randomRotation(std::mt19937& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  return Quat(g(rng), g(rng), g(rng), g(rng)).normalized();
}

double angleDeg(const Vec3& a, const Vec3& b) {
  return std::acos(std::clamp(a.dot(b), -1.0, 1.0)) * 180.0 / std::numbers::pi;
}

}  // namespace

SweepShape sweepBox(Lattice lattice, bool estimated) {
  SourceShape s{SourceShape::Kind::Box, Vec3(0.4, 0.3, 0.3), 0, 0, Vec3::Zero(), {}};
  return make("box", s, BoxShape(s.size), lattice, 0.025, estimated);
}
SweepShape sweepSphere(Lattice lattice, bool estimated) {
  SourceShape s{SourceShape::Kind::Sphere, Vec3::Zero(), 0.25, 0, Vec3::Zero(), {}};
  return make("sphere", s, SphereShape(0.25), lattice, 0.025, estimated);
}
SweepShape sweepCapsule(Lattice lattice, bool estimated) {
  SourceShape s{SourceShape::Kind::Capsule, Vec3::Zero(), 0.12, 0.3, Vec3::Zero(), {}};
  return make("capsule", s, CapsuleShape(0.12, 0.3), lattice, 0.012, estimated);
}
SweepShape sweepCylinder(Lattice lattice, bool estimated) {
  SourceShape s{SourceShape::Kind::Cylinder, Vec3::Zero(), 0.15, 0.4, Vec3::Zero(), {}};
  return make("cylinder", s, CylinderShape(0.15, 0.4), lattice, 0.015, estimated);
}
SweepShape sweepMesh(Lattice lattice, bool estimated) {
  // a 0.4 x 0.3 x 0.25 box as a closed mesh, turned so that no face lies along the lattice
  const Quat turn = (Quat(Eigen::AngleAxisd(0.35, Vec3::UnitZ())) * Quat(Eigen::AngleAxisd(0.6, Vec3::UnitX())) *
                     Quat(Eigen::AngleAxisd(0.2, Vec3::UnitY())))
                        .normalized();
  auto mesh = test::turnedBoxMesh(turn, Vec3(0.2, 0.15, 0.125));
  EXPECT_TRUE(mesh->makeSolid().ok());
  const SourceShape s = test::meshSource(*mesh);
  EXPECT_EQ(s.facePlanes.size(), 6u);
  return make("mesh", s, MeshShape(mesh), lattice, 0.025, estimated);
}
SweepShape sweepPlate(Lattice lattice, bool estimated) {
  SourceShape s{SourceShape::Kind::Box, Vec3(0.5, 0.4, 0.05), 0, 0, Vec3::Zero(), {}};
  return make("plate", s, BoxShape(s.size), lattice, 0.025, estimated);
}

std::string summary(const std::vector<double>& v) {
  char buf[160];
  std::snprintf(buf, sizeof buf, "n %5zu  median %6.2f  p95 %6.2f  p99 %6.2f  max %6.2f deg", v.size(), percentile(v, 0.5),
                percentile(v, 0.95), percentile(v, 0.99), v.empty() ? 0.0 : *std::max_element(v.begin(), v.end()));
  return buf;
}

void printSweep(const std::string& name, const SweepStats& s) {
  std::printf("%-28s all %s\n", name.c_str(), summary(s.all).c_str());
  for (std::size_t k = 0; k < kPlaneCaseCount; ++k)
    if (!s.byCase[k].empty())
      std::printf("%-28s   %-24s %s\n", name.c_str(), planeCaseName(static_cast<PlaneCase>(k)), summary(s.byCase[k]).c_str());
  std::printf("%-28s patches %zu, unvalidated %zu (%.3f %%), convex violations %zu, look-ahead decided %zu, "
              "poses without contact %zu, without reference %zu\n",
              name.c_str(), s.patches, s.unvalidated,
              s.patches ? 100.0 * static_cast<double>(s.unvalidated) / static_cast<double>(s.patches) : 0.0,
              s.convexViolations, s.lookAheadDecided, s.noContact, s.noReference);
  std::fflush(stdout);
}

SweepStats sweepPlanes(const SweepShape& sa, const SweepShape& sb, const SweepSettings& settings) {
  WorldSettings ws;
  ws.gravity = Vec3::Zero();
  World w(ws);
  const MaterialId m = w.addMaterial(Material{"m"});
  BodyDef da, db;
  da.name = "a";
  db.name = "b";
  da.material = db.material = m;
  da.source = sa.source;
  db.source = sb.source;
  db.position = Vec3(10, 0, 0);
  const BodyId a = w.addBody(da, sa.cloud).value();
  const BodyId b = w.addBody(db, sb.cloud).value();
  const SourceShape& coreA = w.bodies().info[a.index()].core;
  const SourceShape& coreB = w.bodies().info[b.index()].core;
  const double rsum = sa.cloud.radii.front() + sb.cloud.radii.front();
  double bound = 0.0;  // a distance at which the cores surely do not touch
  for (const SweepShape* s : {&sa, &sb})
    for (const Vec3& x : s->cloud.positions) bound = std::max(bound, x.norm());
  bound = 2.0 * bound + 2.0 * rsum;

  std::mt19937 rng(settings.seed);
  std::normal_distribution<double> g(0.0, 1.0);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  SweepStats out;
  auto setPose = [&](BodyId id, const Vec3& origin, const Quat& q) {
    BodyState& s = w.bodyState(id);
    const BodyInfo& info = w.bodies().info[id.index()];
    s.orientation = (q * info.principalInShape).normalized();
    s.position = origin + q * info.comInShape;
  };
  const double tol = w.settings().planes.validationTolerance * rsum;
  for (int pose = 0; static_cast<int>(out.all.size()) < settings.poses && pose < 20 * settings.poses; ++pose) {
    // random orientations and direction; B slid along it until the cores are `gap` apart (the distance of
    // two convex sets under translation along a line is convex, so bisection finds it)
    const Quat qa = randomRotation(rng), qb = randomRotation(rng);
    const Vec3 dir = Vec3(g(rng), g(rng), g(rng)).normalized();
    const double overlap = settings.minOverlap + (settings.maxOverlap - settings.minOverlap) * u(rng);
    const double gap = rsum * (1.0 - overlap);
    double lo = 0.0, hi = bound;
    for (int it = 0; it < 60; ++it) {
      const double mid = 0.5 * (lo + hi);
      const reference::CoreContact c = reference::coreContact(coreA, Vec3::Zero(), qa, coreB, dir * mid, qb);
      (c.overlap || c.distance < gap ? lo : hi) = mid;
    }
    const Vec3 pb = dir * hi;
    const reference::CoreContact ref = reference::coreContact(coreA, Vec3::Zero(), qa, coreB, pb, qb);
    if (!ref.valid || std::abs(ref.distance - gap) > 1e-6 * rsum) {
      ++out.noReference;
      continue;
    }
    setPose(a, Vec3::Zero(), qa);
    setPose(b, pb, qb);
    w.syncParticles();
    w.refreshContacts();
    const PatchSet& ps = w.patches();
    out.patches += ps.patches.size();
    const ContactPatch* largest = nullptr;
    for (const ContactPatch& p : ps.patches) {
      if (!p.validated) ++out.unvalidated;
      if (p.lookAhead) ++out.lookAheadDecided;
      if (!largest || p.count > largest->count) largest = &p;
      // the paper's convex property: a plane with the chosen normal separates every particle centre of the two
      // bodies (A's within the validation tolerance below it, B's within as much above)
      if (p.validated) {
        double top = -std::numeric_limits<double>::infinity(), bottom = std::numeric_limits<double>::infinity();
        for (const ParticleId q : w.bodies().info[a.index()].particles) top = std::max(top, p.normal.dot(w.particles().position[q.index()]));
        for (const ParticleId q : w.bodies().info[b.index()].particles)
          bottom = std::min(bottom, p.normal.dot(w.particles().position[q.index()]));
        if (!(bottom - top >= -2.0 * tol)) ++out.convexViolations;
      }
    }
    if (!largest) {
      ++out.noContact;
      continue;
    }
    const double angle = angleDeg(largest->normal, ref.normal);
    out.all.push_back(angle);
    if (const char* dump = std::getenv("VOLPAR_SWEEP_DUMP"); dump && angle > std::atof(dump)) {
      const Vec3 pa = qa.conjugate() * ref.pointA, nl = qa.conjugate() * largest->normal, nr = qa.conjugate() * ref.normal;
      const Vec3 pB = qb.conjugate() * (ref.pointB - pb), nlb = qb.conjugate() * largest->normal, nrb = qb.conjugate() * ref.normal;
      std::fprintf(stderr, "DUMP pose %d %s %.1f src %d cnt %u | A pt %.3f %.3f %.3f n %.3f %.3f %.3f ref %.3f %.3f %.3f | B pt %.3f %.3f %.3f n %.3f %.3f %.3f ref %.3f %.3f %.3f\n",
        pose, planeCaseName(largest->planeCase), angle, static_cast<int>(largest->source), largest->count, pa.x(), pa.y(), pa.z(), nl.x(), nl.y(), nl.z(), nr.x(), nr.y(), nr.z(),
        pB.x(), pB.y(), pB.z(), nlb.x(), nlb.y(), nlb.z(), nrb.x(), nrb.y(), nrb.z());
    }
    out.byCase[static_cast<std::size_t>(largest->planeCase)].push_back(angle);
  }
  return out;
}

}  // namespace volpar::test
