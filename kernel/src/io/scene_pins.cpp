// The pins of a scene's bodies (docs/scenes.md): read with their body, each a set of
// particles chosen by index and/or by a box, fixed or moved along a kinematic path; and
// resolved to particles by the same code when the file is read (ropes and grids, from the
// body's spec) and when the scene is assembled (every body, from the built particles), so
// that both select the same particles and refuse the same pins in the same words.
#include <algorithm>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "scene_internal.hpp"

namespace weft::io_detail {

namespace {

// Box pins of bodies up to this size are checked while reading (each a pass over the
// body's particles), those of larger bodies when the scene is assembled: so that reading
// a short file stays fast however large the bodies it asks for.
constexpr Index kMaxScannedParticles = Index(1) << 20;

bool inBox(const Vec3d& p, const std::pair<Vec3d, Vec3d>& box) {
  const auto& [lo, hi] = box;
  return p.x >= lo.x && p.x <= hi.x && p.y >= lo.y && p.y <= hi.y && p.z >= lo.z && p.z <= hi.z;
}

}  // namespace

std::optional<BodyGeometry> ropeGeometry(const RopeSpec& s) {
  Vec3d d;
  if (!normalised(s.direction, d)) return std::nullopt;
  const double step = s.length / static_cast<double>(s.particleCount - 1);
  return BodyGeometry{s.particleCount, [s, d, step](Index i) {
                        const double t = step * static_cast<double>(i);
                        return Vec3d{s.origin.x + t * d.x, s.origin.y + t * d.y, s.origin.z + t * d.z};
                      }};
}

std::optional<BodyGeometry> gridGeometry(const ClothGridSpec& s) {
  Vec3d u, w;
  if (!normalised(s.rowAxis, u) || !normalised(s.columnAxis, w)) return std::nullopt;
  return BodyGeometry{
      s.width * s.height, [s, u, w](Index i) {
        const Index r = i / s.width, c = i % s.width;
        const double a = s.spacing * static_cast<double>(c), b = s.spacing * static_cast<double>(r);
        return Vec3d{s.origin.x + a * u.x + b * w.x, s.origin.y + a * u.y + b * w.y, s.origin.z + a * u.z + b * w.z};
      }};
}

std::vector<Index> pinSelection(const PinSpec& pin, Index count, const std::function<Vec3d(Index)>& position) {
  std::vector<Index> selected = pin.particles;
  if (pin.box)
    for (Index i = 0; i < count; ++i)
      if (inBox(position(i), *pin.box)) selected.push_back(i);
  std::sort(selected.begin(), selected.end());
  selected.erase(std::unique(selected.begin(), selected.end()), selected.end());
  return selected;
}

std::string PinConflict::what() const {
  const std::string i = "particle " + std::to_string(particle), e = "pins[" + std::to_string(earlier) + "]";
  switch (kind) {
    case Kind::ListedTwice:
      return i + (earlier == pin ? " is listed twice in this pin" : " is already listed by " + e) +
             ": list each particle once";
    case Kind::MovedTwice:
      return i + " is already moved by " + e + ": a particle can follow one path only";
    case Kind::FixedAndMoved:
      break;
  }
  return i + " is both fixed by its index and moved (by this pin and " + e +
         "): take it out of one of them (a path takes precedence over a fixed box, not over a fixed index)";
}

std::optional<PinConflict> pinConflict(const std::vector<PinSpec>& pins,
                                       const std::vector<std::vector<Index>>& selections) {
  using Kind = PinConflict::Kind;
  std::optional<PinConflict> first;  // the one with the lowest (pin, particle)
  const auto keep = [&first](Kind kind, size_t pin, Index particle, size_t earlier) {
    if (!first || pin < first->pin || (pin == first->pin && particle < first->particle))
      first = PinConflict{kind, pin, particle, earlier};
  };
  // (particle, pin) pairs, sorted: the pins of one particle are adjacent, in pin order. A
  // kinematic pin counts with all it selects; a fixed one with the indices it names only,
  // since a path takes precedence over a fixed pin's box (the top edge fixed, a corner of
  // it moved) but not over a fixed index.
  std::vector<std::pair<Index, size_t>> selected, listed;
  for (size_t q = 0; q < pins.size(); ++q) {
    for (const Index i : pins[q].path ? selections[q] : pins[q].particles) selected.emplace_back(i, q);
    for (const Index i : pins[q].particles) listed.emplace_back(i, q);
  }
  std::sort(selected.begin(), selected.end());
  std::optional<size_t> moved, fixed;  // the first pin moving it / fixing it by index
  for (size_t m = 0; m < selected.size(); ++m) {
    const auto [i, q] = selected[m];
    if (m == 0 || i != selected[m - 1].first) moved = fixed = std::nullopt;
    if (pins[q].path) {
      if (moved)
        keep(Kind::MovedTwice, q, i, *moved);
      else if (fixed)
        keep(Kind::FixedAndMoved, q, i, *fixed);
      if (!moved) moved = q;
    } else {
      if (moved) keep(Kind::FixedAndMoved, q, i, *moved);
      if (!fixed) fixed = q;
    }
  }
  // An index written twice: checked after the contradictions, which say more on a tie.
  std::sort(listed.begin(), listed.end());
  for (size_t m = 1; m < listed.size(); ++m)
    if (listed[m].first == listed[m - 1].first)
      keep(Kind::ListedTwice, listed[m].second, listed[m].first, listed[m - 1].second);
  return first;
}

std::string particleRange(Index count) {
  return "the body has " + std::to_string(count) + " particles, 0 .. " + std::to_string(count - 1);
}

std::vector<PinSpec> readPins(const Reader& r, const Json& body, const std::string& field,
                              const BodyGeometry* geometry) {
  std::vector<PinSpec> pins;
  if (!body.contains("pins")) return pins;
  const std::string f = Reader::join(field, "pins");
  const Json& j = body["pins"];
  if (!j.is_array()) r.fail(f, std::string("must be an array, got ") + typeName(j) + " " + shortDump(j));
  const auto index = [&](const Json& v, const std::string& fv) {
    if (!v.is_number_integer() || v.get<std::int64_t>() < 0 || v.get<std::int64_t>() > (1ll << 31) - 1 ||
        (v.is_number_unsigned() && v.get<std::uint64_t>() > (1ull << 31) - 1))
      r.fail(fv, "must be a particle index (an integer >= 0), got " + shortDump(v));
    const Index i = static_cast<Index>(v.get<std::int64_t>());
    if (geometry && i >= geometry->count)
      r.fail(fv, "particle " + std::to_string(i) + " is not in the body (" + particleRange(geometry->count) + ")");
    return i;
  };
  for (size_t k = 0; k < j.size(); ++k) {
    const std::string fk = f + "[" + std::to_string(k) + "]";
    const Json& e = j[k];
    PinSpec p;
    if (e.is_number()) {  // a bare index: that particle, fixed
      p.particles.push_back(index(e, fk));
      pins.push_back(std::move(p));
      continue;
    }
    if (!e.is_object())
      r.fail(fk, std::string("must be a particle index or an object with particles, box, path; got ") + typeName(e) +
                     " " + shortDump(e));
    r.object(e, fk, {"particles", "box", "path"});
    if (e.contains("particles")) {
      const Json& list = e["particles"];
      const std::string fp = fk + ".particles";
      if (!list.is_array() || list.empty())
        r.fail(fp, std::string("must be a non-empty array of particle indices, got ") + typeName(list) + " " +
                       shortDump(list));
      for (size_t q = 0; q < list.size(); ++q)
        p.particles.push_back(index(list[q], fp + "[" + std::to_string(q) + "]"));
    }
    if (e.contains("box")) {
      const std::string fb = fk + ".box";
      r.object(e["box"], fb, {"min", "max"});
      if (!e["box"].contains("min") || !e["box"].contains("max"))
        r.fail(fb, "needs both min and max, got " + shortDump(e["box"]));
      const Vec3d lo = r.vector(e["box"], fb, "min", {}), hi = r.vector(e["box"], fb, "max", {});
      if (!(lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z))
        r.fail(fb, "min must be <= max in every coordinate, got min " + fmt(lo) + ", max " + fmt(hi));
      p.box = std::make_pair(lo, hi);
      if (geometry && geometry->count <= kMaxScannedParticles) {
        bool any = false;
        for (Index i = 0; i < geometry->count && !any; ++i) any = inBox(geometry->position(i), *p.box);
        if (!any)
          r.fail(fb, "selects no particle of the body: none is inside min " + fmt(lo) + ", max " + fmt(hi) +
                         " at the start (the body spans " + fmt(geometry->position(0)) + " .. " +
                         fmt(geometry->position(geometry->count - 1)) + ")");
      }
    }
    if (!e.contains("particles") && !e.contains("box")) r.fail(fk, "needs particles or box, got " + shortDump(e));
    if (e.contains("path")) p.path = readPath(r, e["path"], fk + ".path");
    pins.push_back(std::move(p));
  }
  if (geometry && geometry->count <= kMaxScannedParticles) {
    std::vector<std::vector<Index>> selections(pins.size());
    for (size_t q = 0; q < pins.size(); ++q)  // (pinConflict reads the kinematic pins' selections only)
      if (pins[q].path) selections[q] = pinSelection(pins[q], geometry->count, geometry->position);
    if (const auto conflict = pinConflict(pins, selections))
      r.fail(f + "[" + std::to_string(conflict->pin) + "]", conflict->what());
  }
  return pins;
}

KinematicPath readPath(const Reader& r, const Json& j, const std::string& f) {
  r.object(j, f, {"velocity", "angular_velocity", "axis", "center", "start", "end"});
  KinematicPath p;
  p.velocity = r.vector(j, f, "velocity", p.velocity);
  p.angularVelocity = r.anyNumber(j, f, "angular_velocity", 0);
  p.axis = r.vector(j, f, "axis", p.axis);
  p.center = r.vector(j, f, "center", p.center);
  p.startTime = r.number(j, f, "start", 0, 0, true, " s");
  if (j.contains("end")) {
    p.endTime = r.number(j["end"], Reader::join(f, "end"));
    if (!(p.endTime >= p.startTime))
      r.fail(Reader::join(f, "end"), "must be >= start (" + fmt(p.startTime) + " s), got " + shortDump(j["end"]));
  }
  // The simulation normalises the axis: its length must be finite and non-zero (an
  // infinite one would normalise to 0 and shrink the pinned set instead of turning it).
  Vec3d unit;
  if (p.angularVelocity != 0 && !normalised(p.axis, unit))
    r.fail(Reader::join(f, "axis"),
           "must be a vector of finite non-zero length when angular_velocity is not 0, got " + fmt(p.axis));
  // The kernel's rules (a speed within kMaxSpeed ...), named as this file spells them.
  r.kernelRules(j, f, "path.", [&] { validateKinematicPath(p, "path."); },
                {{"startTime", "start"}, {"endTime", "end"}});
  return p;
}

}  // namespace weft::io_detail
