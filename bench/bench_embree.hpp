// Embree 3 as a peer of weft's BVH (bench_collide.cpp, bench_self_collision.cpp): a device
// and a scene over one mesh. Only where Embree is found (WEFT_HAVE_EMBREE).
#pragma once

#include <embree3/rtcore.h>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <limits>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "weft/weft.hpp"

namespace weftbench {

/// An Embree device and scene over one mesh (float vertices, interleaved and padded as
/// Embree wants them), triangles or user geometry with the triangles' boxes.
struct EmbreeMesh {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  RTCGeometry geometry = nullptr;
  std::vector<float> xyz;  // 3 per vertex + 1 of padding: Embree reads 16 bytes per vertex
  std::vector<unsigned> indices;
  float margin = 0;  // user geometry: boxes grown by this much (m) on every side

  EmbreeMesh(const weft::Vec3Array<float>& x, const weft::Triangles& triangles, int threads, bool user,
             RTCBuildQuality quality, float boxMargin = 0)
      : margin(boxMargin) {
    const std::string config = "threads=" + std::to_string(threads);
    device = rtcNewDevice(config.c_str());
    const weft::Index nv = x.rows(), nt = triangles.count();
    xyz.assign(static_cast<size_t>(3 * nv + 1), 0.0f);
    for (weft::Index i = 0; i < nv; ++i)
      for (int k = 0; k < 3; ++k) xyz[static_cast<size_t>(3 * i + k)] = x(i, k);
    indices.resize(static_cast<size_t>(3 * nt));
    for (weft::Index t = 0; t < nt; ++t) {
      indices[static_cast<size_t>(3 * t)] = static_cast<unsigned>(triangles.a[t]);
      indices[static_cast<size_t>(3 * t + 1)] = static_cast<unsigned>(triangles.b[t]);
      indices[static_cast<size_t>(3 * t + 2)] = static_cast<unsigned>(triangles.c[t]);
    }
    scene = rtcNewScene(device);
    rtcSetSceneBuildQuality(scene, quality == RTC_BUILD_QUALITY_REFIT ? RTC_BUILD_QUALITY_LOW : quality);
    if (quality == RTC_BUILD_QUALITY_REFIT) rtcSetSceneFlags(scene, RTC_SCENE_FLAG_DYNAMIC);
    if (user) {
      geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_USER);
      rtcSetGeometryUserPrimitiveCount(geometry, static_cast<unsigned>(nt));
      rtcSetGeometryUserData(geometry, this);
      rtcSetGeometryBoundsFunction(geometry, &EmbreeMesh::bounds, nullptr);
    } else {
      geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
      rtcSetSharedGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, xyz.data(), 0,
                                 3 * sizeof(float), static_cast<size_t>(nv));
      rtcSetSharedGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, indices.data(), 0,
                                 3 * sizeof(unsigned), static_cast<size_t>(nt));
    }
    rtcSetGeometryBuildQuality(geometry, quality);
    rtcCommitGeometry(geometry);
    rtcAttachGeometry(scene, geometry);
  }
  ~EmbreeMesh() {
    rtcReleaseGeometry(geometry);
    rtcReleaseScene(scene);
    rtcReleaseDevice(device);
  }
  EmbreeMesh(const EmbreeMesh&) = delete;
  EmbreeMesh& operator=(const EmbreeMesh&) = delete;

  /// Marks the vertices changed and commits: a rebuild, or a refit with REFIT quality.
  void commit() {
    if (rtcGetGeometryUserData(geometry) == nullptr) rtcUpdateGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0);
    rtcCommitGeometry(geometry);
    rtcCommitScene(scene);
  }

  static void bounds(const RTCBoundsFunctionArguments* args) {
    const auto* self = static_cast<const EmbreeMesh*>(args->geometryUserPtr);
    const unsigned* corner = &self->indices[3 * static_cast<size_t>(args->primID)];
    RTCBounds& b = *args->bounds_o;
    b.lower_x = b.lower_y = b.lower_z = std::numeric_limits<float>::infinity();
    b.upper_x = b.upper_y = b.upper_z = -std::numeric_limits<float>::infinity();
    for (int k = 0; k < 3; ++k) {
      const float* p = &self->xyz[3 * static_cast<size_t>(corner[k])];
      b.lower_x = std::min(b.lower_x, p[0]);
      b.lower_y = std::min(b.lower_y, p[1]);
      b.lower_z = std::min(b.lower_z, p[2]);
      b.upper_x = std::max(b.upper_x, p[0]);
      b.upper_y = std::max(b.upper_y, p[1]);
      b.upper_z = std::max(b.upper_z, p[2]);
    }
    b.lower_x -= self->margin;
    b.lower_y -= self->margin;
    b.lower_z -= self->margin;
    b.upper_x += self->margin;
    b.upper_y += self->margin;
    b.upper_z += self->margin;
  }
};

/// Every pair of primitives whose boxes overlap between two committed scenes (a scene with
/// itself: each pair in both orders). Embree calls back from its worker threads with a few
/// pairs at a time; each thread appends to its own buffer (found once per thread under a
/// lock, then without one), and the buffers are joined after rtcCollide. (One buffer under
/// one lock made two threads 4-8x slower than one: every callback contended for the lock.)
class EmbreeCollisions {
 public:
  EmbreeCollisions() : id_(nextId()) {}
  EmbreeCollisions(const EmbreeCollisions&) = delete;
  EmbreeCollisions& operator=(const EmbreeCollisions&) = delete;

  void collide(RTCScene a, RTCScene b) {
    for (auto& buffer : buffers_) buffer->clear();
    rtcCollide(a, b, &EmbreeCollisions::collect, this);
    found_.clear();
    for (const auto& buffer : buffers_) found_.insert(found_.end(), buffer->begin(), buffer->end());
  }
  const std::vector<RTCCollision>& found() const { return found_; }

 private:
  static std::uint64_t nextId() {
    static std::atomic<std::uint64_t> counter{0};
    return ++counter;
  }
  /// This thread's buffer for this object (created on the thread's first callback).
  std::vector<RTCCollision>& buffer() {
    struct Cached {
      std::uint64_t owner = 0;
      std::vector<RTCCollision>* buffer = nullptr;
    };
    thread_local Cached cached;
    if (cached.owner != id_) {
      std::lock_guard<std::mutex> guard(lock_);
      buffers_.push_back(std::make_unique<std::vector<RTCCollision>>());
      cached.owner = id_;
      cached.buffer = buffers_.back().get();
    }
    return *cached.buffer;
  }
  static void collect(void* user, RTCCollision* collisions, unsigned count) {
    std::vector<RTCCollision>& out = static_cast<EmbreeCollisions*>(user)->buffer();
    out.insert(out.end(), collisions, collisions + count);
  }
  std::uint64_t id_;
  std::vector<std::unique_ptr<std::vector<RTCCollision>>> buffers_;
  std::vector<RTCCollision> found_;
  std::mutex lock_;
};

}  // namespace weftbench
