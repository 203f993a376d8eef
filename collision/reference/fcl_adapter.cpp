#include "volpar/collision/reference/fcl_adapter.hpp"

#include <fcl/fcl.h>

#include <algorithm>
#include <map>
#include <sstream>

namespace volpar::reference {

namespace {

fcl::Transform3d translation(const Vec3& p) {
  fcl::Transform3d x = fcl::Transform3d::Identity();
  x.translation() = p;
  return x;
}

std::uint32_t tag(const fcl::CollisionObjectd* o) {
  return static_cast<std::uint32_t>(reinterpret_cast<std::uintptr_t>(o->getUserData()));
}

void* asUserData(std::size_t i) { return reinterpret_cast<void*>(static_cast<std::uintptr_t>(i)); }

std::string describe(ParticleId a, ParticleId b) {
  return "particles " + std::to_string(a.value) + " and " + std::to_string(b.value);
}

}  // namespace

struct FclWorldReference::Impl {
  // one sphere object per particle, one box per body, one halfspace per plane
  std::map<double, std::shared_ptr<fcl::Sphered>> spheres;
  std::vector<std::unique_ptr<fcl::CollisionObjectd>> particleObjects;
  std::vector<std::unique_ptr<fcl::CollisionObjectd>> bodyObjects;
  std::vector<std::unique_ptr<fcl::CollisionObjectd>> planeObjects;
  fcl::DynamicAABBTreeCollisionManagerd particleManager;
  fcl::DynamicAABBTreeCollisionManagerd bodyManager;
  bool built = false;

  void build(const ParticleStore& p, const BodyStore& b, std::span<const Aabb> boxes, std::span<const Plane> planes) {
    particleManager.clear();
    bodyManager.clear();
    particleObjects.clear();
    bodyObjects.clear();
    planeObjects.clear();
    std::vector<fcl::CollisionObjectd*> raw;
    for (std::size_t i = 0; i < p.size(); ++i) {
      auto& sphere = spheres[p.radius[i]];
      if (!sphere) sphere = std::make_shared<fcl::Sphered>(p.radius[i]);
      particleObjects.push_back(std::make_unique<fcl::CollisionObjectd>(sphere, translation(p.position[i])));
      particleObjects.back()->setUserData(asUserData(i));
      raw.push_back(particleObjects.back().get());
    }
    particleManager.registerObjects(raw);
    particleManager.setup();
    raw.clear();
    for (std::size_t i = 0; i < b.size(); ++i) {
      const Vec3 size = boxes[i].hi - boxes[i].lo;
      bodyObjects.push_back(std::make_unique<fcl::CollisionObjectd>(
          std::make_shared<fcl::Boxd>(size.x(), size.y(), size.z()), translation(boxes[i].centre())));
      bodyObjects.back()->setUserData(asUserData(i));
      raw.push_back(bodyObjects.back().get());
    }
    bodyManager.registerObjects(raw);
    bodyManager.setup();
    for (const Plane& pl : planes)
      planeObjects.push_back(std::make_unique<fcl::CollisionObjectd>(std::make_shared<fcl::Halfspaced>(pl.normal, pl.offset)));
    built = true;
  }

  void update(const ParticleStore& p, std::span<const Aabb> boxes) {
    for (std::size_t i = 0; i < p.size(); ++i) {
      particleObjects[i]->setTranslation(p.position[i]);
      particleObjects[i]->computeAABB();
    }
    particleManager.update();  // without computeAABB() and update() moved objects are missed (FCL #629)
    for (std::size_t i = 0; i < boxes.size(); ++i) {
      const Vec3 size = boxes[i].hi - boxes[i].lo;
      bodyObjects[i] = std::make_unique<fcl::CollisionObjectd>(std::make_shared<fcl::Boxd>(size.x(), size.y(), size.z()),
                                                               translation(boxes[i].centre()));
      bodyObjects[i]->setUserData(asUserData(i));
    }
    std::vector<fcl::CollisionObjectd*> raw;
    for (auto& o : bodyObjects) raw.push_back(o.get());
    bodyManager.clear();
    bodyManager.registerObjects(raw);
    bodyManager.setup();
  }
};

FclWorldReference::FclWorldReference() : impl_(std::make_unique<Impl>()) {}
FclWorldReference::~FclWorldReference() = default;

FclReport FclWorldReference::collide(const ParticleStore& p, const BodyStore& b, std::span<const Aabb> boxes,
                                     std::span<const Plane> planes, const SelfContactFilter& selfContact) {
  Impl& m = *impl_;
  if (!m.built || m.particleObjects.size() != p.size() || m.bodyObjects.size() != b.size() ||
      m.planeObjects.size() != planes.size())
    m.build(p, b, boxes, planes);
  else
    m.update(p, boxes);
  FclReport report;

  // body level: FCL's broadphase over the bodies' tight boxes
  struct BoxData {
    const BodyStore* bodies;
    std::vector<BodyPair>* out;
  } boxData{&b, &report.boxPairs};
  m.bodyManager.collide(&boxData, [](fcl::CollisionObjectd* o1, fcl::CollisionObjectd* o2, void* data) {
    auto* d = static_cast<BoxData*>(data);
    fcl::CollisionRequestd req;
    fcl::CollisionResultd res;
    if (!fcl::collide(o1, o2, req, res)) return false;
    const BodyId x(tag(o1)), y(tag(o2));
    // bodies that broke apart have no particles any more
    if (!d->bodies->info[x.index()].alive || !d->bodies->info[y.index()].alive) return false;
    const bool bothStatic = d->bodies->info[x.index()].kind == BodyKind::Static &&
                            d->bodies->info[y.index()].kind == BodyKind::Static;
    if (!bothStatic) d->out->push_back(x < y ? BodyPair{x, y} : BodyPair{y, x});
    return false;
  });

  // particle level: FCL's broadphase and sphere-sphere narrow phase over every particle
  struct SphereData {
    const ParticleStore* particles;
    const BodyStore* bodies;
    const SelfContactFilter* self;
    std::vector<SpherePair>* out;
  } sphereData{&p, &b, &selfContact, &report.spherePairs};
  m.particleManager.collide(&sphereData, [](fcl::CollisionObjectd* o1, fcl::CollisionObjectd* o2, void* data) {
    auto* d = static_cast<SphereData*>(data);
    ParticleId x(tag(o1)), y(tag(o2));
    const BodyId bx = d->particles->body[x.index()], by = d->particles->body[y.index()];
    if (bx == by) {
      if (d->bodies->info[bx.index()].kind != BodyKind::Deformable || !(*d->self)(x, y)) return false;
    } else if (d->bodies->info[bx.index()].kind == BodyKind::Static && d->bodies->info[by.index()].kind == BodyKind::Static) {
      return false;
    }
    fcl::CollisionRequestd req;
    fcl::CollisionResultd res;
    if (!fcl::collide(o1, o2, req, res)) return false;
    // order as volpar does: the particle of the lower body first, ascending ids inside one body
    if (by < bx || (bx == by && y < x)) std::swap(x, y);
    const double dist = (o2->getTranslation() - o1->getTranslation()).norm();
    d->out->push_back({x, y, dist});
    return false;
  });

  // planes: FCL sphere-halfspace for every particle of a moving body
  for (std::size_t k = 0; k < planes.size(); ++k) {
    for (std::size_t i = 0; i < p.size(); ++i) {
      if (b.info[p.body[i].index()].kind == BodyKind::Static) continue;
      fcl::CollisionRequestd req;
      fcl::CollisionResultd res;
      if (fcl::collide(m.particleObjects[i].get(), m.planeObjects[k].get(), req, res))
        report.planeTouches.push_back({ParticleId(i), PlaneId(k), planes[k].normal.dot(p.position[i]) - planes[k].offset});
    }
  }

  std::sort(report.boxPairs.begin(), report.boxPairs.end());
  report.boxPairs.erase(std::unique(report.boxPairs.begin(), report.boxPairs.end()), report.boxPairs.end());
  std::sort(report.spherePairs.begin(), report.spherePairs.end());
  std::sort(report.planeTouches.begin(), report.planeTouches.end());
  for (const SpherePair& s : report.spherePairs) {
    const BodyId x = p.body[s.a.index()], y = p.body[s.b.index()];
    if (x != y) report.touchingBodies.push_back({x, y});
  }
  report.touchingBodies.erase(std::unique(report.touchingBodies.begin(), report.touchingBodies.end()),
                              report.touchingBodies.end());
  return report;
}

namespace {

std::shared_ptr<fcl::CollisionGeometryd> geometry(const SourceShape& s) {
  switch (s.kind) {
    case SourceShape::Kind::Box: return std::make_shared<fcl::Boxd>(s.size.x(), s.size.y(), s.size.z());
    case SourceShape::Kind::Sphere: return std::make_shared<fcl::Sphered>(s.radius);
    case SourceShape::Kind::Cylinder: return std::make_shared<fcl::Cylinderd>(s.radius, s.length);
    case SourceShape::Kind::Capsule: return std::make_shared<fcl::Capsuled>(s.radius, s.length);
    default: return nullptr;
  }
}

}  // namespace

PrimitiveContact primitiveContact(const SourceShape& sa, const Vec3& pa, const Quat& qa, const SourceShape& sb,
                                  const Vec3& pb, const Quat& qb) {
  PrimitiveContact rc;
  auto ga = geometry(sa), gb = geometry(sb);
  if (!ga || !gb) return rc;
  fcl::Transform3d xa = fcl::Transform3d::Identity(), xb = fcl::Transform3d::Identity();
  xa.linear() = qa.toRotationMatrix();
  xa.translation() = pa;
  xb.linear() = qb.toRotationMatrix();
  xb.translation() = pb;
  fcl::CollisionObjectd a(ga, xa), b(gb, xb);
  fcl::CollisionRequestd req(16, true);
  fcl::CollisionResultd res;
  if (!fcl::collide(&a, &b, req, res)) return rc;
  rc.hit = true;
  using K = SourceShape::Kind;
  const fcl::Contactd* deepest = &res.getContact(0);
  for (std::size_t i = 1; i < res.numContacts(); ++i)
    if (res.getContact(i).penetration_depth > deepest->penetration_depth) deepest = &res.getContact(i);
  // closed forms (a sphere) and box-box (FCL's SAT, face normals exact) come from collide() itself
  if (sa.kind == K::Sphere || sb.kind == K::Sphere || (sa.kind == K::Box && sb.kind == K::Box)) {
    rc.depth = deepest->penetration_depth;
    rc.normal = deepest->normal;
    rc.normalValid = deepest->normal.norm() > 0.5;
    return rc;
  }
  // libccd's EPA can fail an assertion (which aborts: libfcl is built with asserts) on barely touching
  // shapes; such poses get no reference normal
  const double scale = std::max(ga->aabb_radius, gb->aabb_radius);
  if (!(deepest->penetration_depth > 1e-4 * scale)) return rc;
  const bool capsules = sa.kind == K::Capsule && sb.kind == K::Capsule;
  fcl::DistanceRequestd dreq(true, !capsules);
  fcl::DistanceResultd dres;
  try {
    fcl::distance(&a, &b, dreq, dres);
  } catch (const std::exception&) {
    return rc;  // EPA gave up in a degenerate pose: no reference
  }
  if (dres.min_distance < 0) {
    rc.depth = -dres.min_distance;
    const Vec3 d = dres.nearest_points[0] - dres.nearest_points[1];
    rc.normalValid = d.norm() > 1e-12;
    if (rc.normalValid) rc.normal = d.normalized();
  }
  return rc;
}

std::vector<Vec3> polytopeVertices(const std::vector<std::pair<Vec3, double>>& planes) {
  std::vector<Vec3> out;
  const std::size_t n = planes.size();
  double scale = 0.0;
  for (const auto& [normal, d] : planes) scale = std::max(scale, std::abs(d));
  const double tol = 1e-9 * std::max(scale, 1e-9);
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = i + 1; j < n; ++j)
      for (std::size_t k = j + 1; k < n; ++k) {
        Mat3 m;
        m.row(0) = planes[i].first.transpose();
        m.row(1) = planes[j].first.transpose();
        m.row(2) = planes[k].first.transpose();
        if (std::abs(m.determinant()) < 1e-9) continue;
        const Vec3 x = m.partialPivLu().solve(Vec3(planes[i].second, planes[j].second, planes[k].second));
        bool inside = true;
        for (const auto& [normal, d] : planes) inside = inside && normal.dot(x) <= d + tol;
        if (!inside) continue;
        if (std::none_of(out.begin(), out.end(), [&](const Vec3& v) { return (v - x).norm() <= 10 * tol; })) out.push_back(x);
      }
  return out;
}

namespace {

/// A convex polytope as FCL's Convex: the vertices of its planes, each face's vertices counter-clockwise
/// seen from outside.
std::shared_ptr<fcl::CollisionGeometryd> convexGeometry(const std::vector<std::pair<Vec3, double>>& planes) {
  const std::vector<Vec3> vertices = polytopeVertices(planes);
  if (vertices.size() < 4) return nullptr;
  double scale = 0.0;
  for (const Vec3& v : vertices) scale = std::max(scale, v.norm());
  auto points = std::make_shared<std::vector<fcl::Vector3d>>(vertices.begin(), vertices.end());
  auto faces = std::make_shared<std::vector<int>>();
  int count = 0;
  for (const auto& [normal, d] : planes) {
    std::vector<int> on;
    Vec3 centre = Vec3::Zero();
    for (std::size_t v = 0; v < vertices.size(); ++v)
      if (std::abs(normal.dot(vertices[v]) - d) <= 1e-7 * std::max(scale, 1e-9)) {
        on.push_back(static_cast<int>(v));
        centre += vertices[v];
      }
    if (on.size() < 3) continue;
    centre /= static_cast<double>(on.size());
    const Vec3 u = (vertices[static_cast<std::size_t>(on[0])] - centre).normalized();
    const Vec3 w = normal.cross(u);
    std::sort(on.begin(), on.end(), [&](int x, int y) {
      const Vec3 dx = vertices[static_cast<std::size_t>(x)] - centre, dy = vertices[static_cast<std::size_t>(y)] - centre;
      return std::atan2(dx.dot(w), dx.dot(u)) < std::atan2(dy.dot(w), dy.dot(u));
    });
    faces->push_back(static_cast<int>(on.size()));
    faces->insert(faces->end(), on.begin(), on.end());
    ++count;
  }
  return std::make_shared<fcl::Convexd>(points, count, faces);
}

/// The geometry of a core; flat cores (a one-layer plate, a chain) get a sliver of thickness so that the
/// distance queries stay well posed.
std::shared_ptr<fcl::CollisionGeometryd> coreGeometry(const SourceShape& s) {
  const double sliver = 1e-7;
  switch (s.kind) {
    case SourceShape::Kind::Box: {
      const Vec3 size = s.size.cwiseMax(sliver);
      return std::make_shared<fcl::Boxd>(size.x(), size.y(), size.z());
    }
    case SourceShape::Kind::Sphere: return std::make_shared<fcl::Sphered>(std::max(s.radius, sliver));
    case SourceShape::Kind::Cylinder:
      return std::make_shared<fcl::Cylinderd>(std::max(s.radius, sliver), std::max(s.length, sliver));
    case SourceShape::Kind::Capsule: return std::make_shared<fcl::Capsuled>(std::max(s.radius, sliver), s.length);
    case SourceShape::Kind::Mesh: return s.facePlanes.empty() ? nullptr : convexGeometry(s.facePlanes);
    default: return nullptr;
  }
}

}  // namespace

CoreContact coreContact(const SourceShape& sa, const Vec3& pa, const Quat& qa, const SourceShape& sb, const Vec3& pb,
                        const Quat& qb) {
  CoreContact rc;
  auto ga = coreGeometry(sa), gb = coreGeometry(sb);
  if (!ga || !gb) return rc;
  fcl::Transform3d xa = fcl::Transform3d::Identity(), xb = fcl::Transform3d::Identity();
  xa.linear() = qa.toRotationMatrix();
  xa.translation() = pa + qa * sa.centre;
  xb.linear() = qb.toRotationMatrix();
  xb.translation() = pb + qb * sb.centre;
  fcl::CollisionObjectd a(ga, xa), b(gb, xb);
  fcl::DistanceRequestd req(true, false);
  req.distance_tolerance = 1e-12;
  req.gjk_solver_type = fcl::GST_LIBCCD;
  fcl::DistanceResultd res;
  try {
    fcl::distance(&a, &b, req, res);
  } catch (const std::exception&) {
    return rc;  // GJK gave up in a degenerate pose: no reference
  }
  if (!(res.min_distance > 0.0)) {
    rc.overlap = true;
    return rc;
  }
  rc.distance = res.min_distance;
  rc.pointA = res.nearest_points[0];
  rc.pointB = res.nearest_points[1];
  const Vec3 d = rc.pointB - rc.pointA;
  rc.valid = d.norm() > 1e-12;
  if (rc.valid) rc.normal = d.normalized();
  return rc;
}

std::vector<Vec3> flatFaceNormals(const SourceShape& s, const Quat& q) {
  std::vector<Vec3> out;
  if (s.kind == SourceShape::Kind::Box)
    for (int k = 0; k < 3; ++k) {
      out.push_back(q * Vec3::Unit(k));
      out.push_back(-(q * Vec3::Unit(k)));
    }
  if (s.kind == SourceShape::Kind::Cylinder) {
    out.push_back(q * Vec3::UnitZ());
    out.push_back(-(q * Vec3::UnitZ()));
  }
  return out;
}

Comparison& Comparison::operator+=(const Comparison& o) {
  bodyPairMismatches += o.bodyPairMismatches;
  particlePairMismatches += o.particlePairMismatches;
  planeContactMismatches += o.planeContactMismatches;
  contactsChecked += o.contactsChecked;
  grazing += o.grazing;
  for (const auto& d : o.details)
    if (details.size() < 20) details.push_back(d);
  return *this;
}

Comparison compareContacts(const FclReport& fcl, std::span<const BodyPair> pairs, std::span<const BodyPlanePair> /*planePairs*/,
                           const ContactSet& contacts, const ParticleStore& particles, std::size_t maxDetails) {
  Comparison c;
  auto note = [&](const std::string& s) {
    if (c.details.size() < maxDetails) c.details.push_back(s);
  };
  // every pair FCL sees overlapping or touching must be a broadphase candidate
  for (const auto* list : {&fcl.boxPairs, &fcl.touchingBodies})
    for (const BodyPair& bp : *list)
      if (!std::binary_search(pairs.begin(), pairs.end(), bp)) {
        ++c.bodyPairMismatches;
        note("bodies " + std::to_string(bp.a.value) + " and " + std::to_string(bp.b.value) +
             (list == &fcl.boxPairs ? " have overlapping boxes" : " touch") + " in FCL but are not a broadphase pair");
      }

  // particle pairs, grazing ones left out on both sides
  auto grazingPair = [&](ParticleId a, ParticleId b, double distance) {
    const double rsum = particles.radius[a.index()] + particles.radius[b.index()];
    return std::abs(distance - rsum) <= kGrazing * rsum;
  };
  std::vector<SpherePair> ours;
  std::vector<PlaneTouch> ourPlanes;
  for (const ParticleContact& pc : contacts.contacts) {
    // speculative contacts (clearly apart) are not touching pairs; near-zero ones go to the grazing band
    const double scale = particles.radius[pc.a.index()] + (pc.b.valid() ? particles.radius[pc.b.index()] : 0.0);
    if (pc.depth < -kGrazing * scale) continue;
    if (pc.plane.valid()) {
      const double r = particles.radius[pc.a.index()];
      ourPlanes.push_back({pc.a, pc.plane, r - pc.depth});
    } else {
      const double rsum = particles.radius[pc.a.index()] + particles.radius[pc.b.index()];
      ours.push_back({pc.a, pc.b, rsum - pc.depth});
    }
  }
  std::sort(ours.begin(), ours.end());
  std::sort(ourPlanes.begin(), ourPlanes.end());
  std::vector<SpherePair> reference;
  for (const SpherePair& s : fcl.spherePairs) {
    if (grazingPair(s.a, s.b, s.distance)) ++c.grazing;
    else reference.push_back(s);
  }
  std::erase_if(ours, [&](const SpherePair& s) { return grazingPair(s.a, s.b, s.distance); });
  c.contactsChecked += reference.size();
  std::vector<SpherePair> onlyFcl, onlyOurs;
  std::set_difference(reference.begin(), reference.end(), ours.begin(), ours.end(), std::back_inserter(onlyFcl));
  std::set_difference(ours.begin(), ours.end(), reference.begin(), reference.end(), std::back_inserter(onlyOurs));
  c.particlePairMismatches = onlyFcl.size() + onlyOurs.size();
  for (const SpherePair& s : onlyFcl) note(describe(s.a, s.b) + " touch in FCL (distance " + std::to_string(s.distance) + ") but not in volpar");
  for (const SpherePair& s : onlyOurs) note(describe(s.a, s.b) + " touch in volpar (distance " + std::to_string(s.distance) + ") but not in FCL");

  // plane contacts
  auto grazingPlane = [&](const PlaneTouch& t) {
    const double r = particles.radius[t.particle.index()];
    return std::abs(t.height - r) <= kGrazing * r;
  };
  std::vector<PlaneTouch> planeRef;
  for (const PlaneTouch& t : fcl.planeTouches) {
    if (grazingPlane(t)) ++c.grazing;
    else planeRef.push_back(t);
  }
  std::erase_if(ourPlanes, grazingPlane);
  c.contactsChecked += planeRef.size();
  std::vector<PlaneTouch> planeOnlyFcl, planeOnlyOurs;
  std::set_difference(planeRef.begin(), planeRef.end(), ourPlanes.begin(), ourPlanes.end(), std::back_inserter(planeOnlyFcl));
  std::set_difference(ourPlanes.begin(), ourPlanes.end(), planeRef.begin(), planeRef.end(), std::back_inserter(planeOnlyOurs));
  c.planeContactMismatches = planeOnlyFcl.size() + planeOnlyOurs.size();
  for (const PlaneTouch& t : planeOnlyFcl)
    note("particle " + std::to_string(t.particle.value) + " touches plane " + std::to_string(t.plane.value) + " in FCL but not in volpar");
  for (const PlaneTouch& t : planeOnlyOurs)
    note("particle " + std::to_string(t.particle.value) + " touches plane " + std::to_string(t.plane.value) + " in volpar but not in FCL");
  return c;
}

}  // namespace volpar::reference
