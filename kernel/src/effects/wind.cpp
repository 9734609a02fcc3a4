#include "wind.hpp"

#include <algorithm>
#include <cmath>

namespace weft::detail {

namespace {

// SplitMix64 (Steele, Lea & Flood 2014): a tiny generator with a fixed, documented output
// sequence, so a seed gives the same gusts everywhere (std:: distributions do not promise
// that across standard libraries).
struct SplitMix64 {
  std::uint64_t state;
  std::uint64_t next() {
    std::uint64_t z = (state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  double uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }  // [0, 1)
};

constexpr double kTwoPi = 6.28318530717958647693;

// A uniformly distributed unit vector (Archimedes: z uniform in [-1, 1], azimuth uniform).
void unitVector(SplitMix64& rng, double& x, double& y, double& z) {
  z = 2 * rng.uniform() - 1;
  const double azimuth = kTwoPi * rng.uniform();
  const double r = std::sqrt(std::max(0.0, 1 - z * z));
  x = r * portableSine(azimuth + kTwoPi / 4);
  y = r * portableSine(azimuth);
}

// u_i = U - v_i + sum_j A_j sin(k_j . x_i + psi_j) over [0, count); pointers offset.
template <class S>
[[gnu::noinline]] void relativeAir(Index count, const S* __restrict x, const S* __restrict y, const S* __restrict z,
                                   const S* __restrict vx, const S* __restrict vy, const S* __restrict vz, S Ux, S Uy,
                                   S Uz, int modes, const S* kx, const S* ky, const S* kz, const S* psi, const S* Ax,
                                   const S* Ay, const S* Az, S* __restrict ux, S* __restrict uy, S* __restrict uz) {
  for (Index i = 0; i < count; ++i) {
    ux[i] = Ux - vx[i];
    uy[i] = Uy - vy[i];
    uz[i] = Uz - vz[i];
  }
  for (int j = 0; j < modes; ++j) {
    const S kxj = kx[j], kyj = ky[j], kzj = kz[j], pj = psi[j], axj = Ax[j], ayj = Ay[j], azj = Az[j];
    for (Index i = 0; i < count; ++i) {
      const S s = portableSine(kxj * x[i] + kyj * y[i] + kzj * z[i] + pj);
      ux[i] += axj * s;
      uy[i] += ayj * s;
      uz[i] += azj * s;
    }
  }
}

// A third of the aerodynamic force of the triangle with corners (i, j, k), f (see
// effects.hpp): with c = (x_j - x_i) x (x_k - x_i) (|c| = 2 area), n = c / |c|, u_n = u . n,
//   f_D + f_L = rho |c| / 4 ((C_D + C_L) |u| u_n n - C_L u_n^2 u / |u|),
// u the mean relative air velocity of the corners.
template <class S>
inline void triangleForce(S xi, S yi, S zi, S xj, S yj, S zj, S xk, S yk, S zk, S u0, S u1, S u2, S rho, S cd, S cl,
                          S& fx, S& fy, S& fz) {
  const S e1x = xj - xi, e1y = yj - yi, e1z = zj - zi;
  const S e2x = xk - xi, e2y = yk - yi, e2z = zk - zi;
  const S cx = e1y * e2z - e1z * e2y, cy = e1z * e2x - e1x * e2z, cz = e1x * e2y - e1y * e2x;
  // With q = 1 / (|c| |u|) (one square root, one division):
  //   rho |c| / 12 (C_D + C_L) |u| u_n / |c|  =  rho / 12 (C_D + C_L) (u . c) (u . u) q   (times c)
  //   rho |c| / 12 C_L u_n^2 / |u|            =  rho / 12 C_L (u . c)^2 q                 (times u)
  const S uc = u0 * cx + u1 * cy + u2 * cz;
  const S uu = u0 * u0 + u1 * u1 + u2 * u2;
  const S cu = (cx * cx + cy * cy + cz * cz) * uu;
  const S q = cu > S(0) ? S(1) / std::sqrt(cu) : S(0);
  const S common = rho * (S(1) / S(12)) * q * uc;
  const S normal = common * (cd + cl) * uu;  // times c
  const S along = -common * cl * uc;         // times u
  fx = normal * cx + along * u0;
  fy = normal * cy + along * u1;
  fz = normal * cz + along * u2;
}

// Triangles [b, e) of an index list into f[t].
template <class S>
[[gnu::noinline]] void triangleForces(Index b, Index e, const Index* __restrict A, const Index* __restrict B,
                                      const Index* __restrict C, const S* __restrict x, const S* __restrict y,
                                      const S* __restrict z, const S* __restrict ux, const S* __restrict uy,
                                      const S* __restrict uz, S rho, S cd, S cl, S* __restrict fx, S* __restrict fy,
                                      S* __restrict fz) {
  const S third = S(1) / S(3);
  for (Index t = b; t < e; ++t) {
    const Index i = A[t], j = B[t], k = C[t];
    triangleForce(x[i], y[i], z[i], x[j], y[j], z[j], x[k], y[k], z[k], (ux[i] + ux[j] + ux[k]) * third,
                  (uy[i] + uy[j] + uy[k]) * third, (uz[i] + uz[j] + uz[k]) * third, rho, cd, cl, fx[t], fy[t], fz[t]);
  }
}

// The two triangles of `count` consecutive grid cells of a row, cell t with top-left
// particle t (pointers offset to the first): (t, t+1, t+W+1) into f1[t] and (t, t+W+1, t+W)
// into f2[t]. Contiguous loads only, like the spring stencil.
template <class S>
[[gnu::noinline]] void gridTriangleForces(Index count, Index W, const S* __restrict x, const S* __restrict y,
                                          const S* __restrict z, const S* __restrict ux, const S* __restrict uy,
                                          const S* __restrict uz, S rho, S cd, S cl, S* __restrict f1x,
                                          S* __restrict f1y, S* __restrict f1z, S* __restrict f2x, S* __restrict f2y,
                                          S* __restrict f2z) {
  const S third = S(1) / S(3);
  for (Index t = 0; t < count; ++t) {
    const Index b = t + 1, d = t + W, e = t + W + 1;
    triangleForce(x[t], y[t], z[t], x[b], y[b], z[b], x[e], y[e], z[e], (ux[t] + ux[b] + ux[e]) * third,
                  (uy[t] + uy[b] + uy[e]) * third, (uz[t] + uz[b] + uz[e]) * third, rho, cd, cl, f1x[t], f1y[t],
                  f1z[t]);
    triangleForce(x[t], y[t], z[t], x[e], y[e], z[e], x[d], y[d], z[d], (ux[t] + ux[e] + ux[d]) * third,
                  (uy[t] + uy[e] + uy[d]) * third, (uz[t] + uz[e] + uz[d]) * third, rho, cd, cl, f2x[t], f2y[t],
                  f2z[t]);
  }
}

// a_p += w_p (f1[p] + f1[p-1] + f1[p-W-1] + f2[p] + f2[p-W-1] + f2[p-W]) over [0, count): the
// six triangles around grid particle p (slots of cells that do not exist hold zero).
// f pointers offset to the first particle's slot, w and a to the first particle.
template <class S>
[[gnu::noinline]] void gridGather(Index count, Index W, const S* __restrict w, const S* __restrict f1x,
                                  const S* __restrict f1y, const S* __restrict f1z, const S* __restrict f2x,
                                  const S* __restrict f2y, const S* __restrict f2z, S* __restrict ax, S* __restrict ay,
                                  S* __restrict az) {
  for (Index p = 0; p < count; ++p) {
    ax[p] += w[p] * (f1x[p] + f1x[p - 1] + f1x[p - W - 1] + f2x[p] + f2x[p - W - 1] + f2x[p - W]);
    ay[p] += w[p] * (f1y[p] + f1y[p - 1] + f1y[p - W - 1] + f2y[p] + f2y[p - W - 1] + f2y[p - W]);
    az[p] += w[p] * (f1z[p] + f1z[p - 1] + f1z[p - W - 1] + f2z[p] + f2z[p - W - 1] + f2z[p - W]);
  }
}

}  // namespace

GustModes::GustModes(const WindEffect& wind) {
  if (!(wind.gustStrength > 0)) return;
  SplitMix64 rng{wind.seed};
  const int K = wind.gustModes;
  const double amplitude = wind.gustStrength * std::sqrt(2.0 / K);  // rms of |gust| = gustStrength
  for (int j = 0; j < K; ++j) {
    double dx, dy, dz, ex, ey, ez;
    unitVector(rng, dx, dy, dz);
    const double wavelength = wind.gustScale * (0.5 + rng.uniform());
    const double period = wind.gustPeriod * (0.5 + rng.uniform());
    const double phi = kTwoPi * rng.uniform();
    unitVector(rng, ex, ey, ez);
    const double kk = kTwoPi / wavelength;
    kx.push_back(kk * dx);
    ky.push_back(kk * dy);
    kz.push_back(kk * dz);
    // Frozen into the mean flow: sin(k . (x - U t) - w t + phi).
    omega.push_back(kTwoPi / period + kk * (dx * wind.velocity.x + dy * wind.velocity.y + dz * wind.velocity.z));
    phase.push_back(phi);
    ax.push_back(amplitude * ex);
    ay.push_back(amplitude * ey);
    az.push_back(amplitude * ez);
  }
}

template <class S>
WindForce<S>::WindForce(const Model<S>& model, const WindEffect& wind) : model_(&model), wind_(wind), modes_(wind) {
  const Index n = model.particleCount();
  const Triangles& tr = model.triangles();
  const Index nt = tr.count();
  for (int j = 0; j < modes_.count(); ++j) {
    mkx_.push_back(static_cast<S>(modes_.kx[j]));
    mky_.push_back(static_cast<S>(modes_.ky[j]));
    mkz_.push_back(static_cast<S>(modes_.kz[j]));
    max_.push_back(static_cast<S>(modes_.ax[j]));
    may_.push_back(static_cast<S>(modes_.ay[j]));
    maz_.push_back(static_cast<S>(modes_.az[j]));
  }
  psi_.assign(modes_.count(), S(0));
  relative_.setZero(n, 3);
  // A cloth grid whose triangles are exactly addClothGrid's (two per cell, in cell order)
  // takes the stencil path: contiguous loads, no index lists.
  if (model.trianglesFormGrid()) {
    const Index W = model.grid()->width;
    gridWidth_ = W;
    gridHeight_ = model.grid()->height;
    // Slot of cell a is a + W + 1, so that the gather's p - W - 1 never goes below 0;
    // slots of cells that do not exist (last column, last row, the front pad) stay 0.
    cellForce_.assign(static_cast<size_t>(6) * (n + W + 1), S(0));
    return;
  }
  triangleForce_.setZero(nt, 3);
  incidence_ = &model.triangleIncidence();  // particle -> triangles, built once per Model
}

template <class S>
void WindForce<S>::prepare(const Vec3Array<S>& x, const Vec3Array<S>& v, double time, const Executor& exec) {
  // Phases reduced in double, so a float model keeps its gusts smooth at large times.
  for (int j = 0; j < modes_.count(); ++j)
    psi_[j] = static_cast<S>(std::fmod(modes_.phase[j] - modes_.omega[j] * time, kTwoPi));
  const Index n = model_->particleCount();
  const S Ux = static_cast<S>(wind_.velocity.x), Uy = static_cast<S>(wind_.velocity.y),
          Uz = static_cast<S>(wind_.velocity.z);
  const int K = modes_.count();
  exec.parallelFor(n, 1024, [&](Index b, Index e) {
    relativeAir(e - b, x.col(0).data() + b, x.col(1).data() + b, x.col(2).data() + b, v.col(0).data() + b,
                v.col(1).data() + b, v.col(2).data() + b, Ux, Uy, Uz, K, mkx_.data(), mky_.data(), mkz_.data(),
                psi_.data(), max_.data(), may_.data(), maz_.data(), relative_.col(0).data() + b,
                relative_.col(1).data() + b, relative_.col(2).data() + b);
  });
  const Triangles& tr = model_->triangles();
  const S rho = static_cast<S>(wind_.airDensity), cd = static_cast<S>(wind_.dragCoefficient),
          cl = static_cast<S>(wind_.liftCoefficient);
  if (gridWidth_ > 0) {
    const Index W = gridWidth_, stride = n + W + 1;
    S* f = cellForce_.data() + W + 1;
    exec.parallelFor(gridHeight_ - 1, std::max<Index>(1, 4096 / W), [&](Index r0, Index r1) {
      for (Index r = r0; r < r1; ++r) {
        const Index a = r * W;
        gridTriangleForces(W - 1, W, x.col(0).data() + a, x.col(1).data() + a, x.col(2).data() + a,
                           relative_.col(0).data() + a, relative_.col(1).data() + a, relative_.col(2).data() + a, rho,
                           cd, cl, f + a, f + stride + a, f + 2 * stride + a, f + 3 * stride + a, f + 4 * stride + a,
                           f + 5 * stride + a);
      }
    });
    return;
  }
  exec.parallelFor(tr.count(), 4096, [&](Index b, Index e) {
    triangleForces(b, e, tr.a.data(), tr.b.data(), tr.c.data(), x.col(0).data(), x.col(1).data(), x.col(2).data(),
                   relative_.col(0).data(), relative_.col(1).data(), relative_.col(2).data(), rho, cd, cl,
                   triangleForce_.col(0).data(), triangleForce_.col(1).data(), triangleForce_.col(2).data());
  });
}

template <class S>
void WindForce<S>::add(Index begin, Index count, S* ax, S* ay, S* az) const {
  const S* __restrict w = model_->inverseMass().data();
  const S* __restrict Fx = triangleForce_.col(0).data();
  const S* __restrict Fy = triangleForce_.col(1).data();
  const S* __restrict Fz = triangleForce_.col(2).data();
  const S* __restrict ux = relative_.col(0).data();
  const S* __restrict uy = relative_.col(1).data();
  const S* __restrict uz = relative_.col(2).data();
  if (gridWidth_ > 0) {
    const Index W = gridWidth_, stride = model_->particleCount() + W + 1;
    const S* f = cellForce_.data() + W + 1 + begin;
    gridGather(count, W, w + begin, f, f + stride, f + 2 * stride, f + 3 * stride, f + 4 * stride, f + 5 * stride, ax,
               ay, az);
    return;
  }
  const Index* __restrict off = incidence_->offsets.data();
  const Index* __restrict inc = incidence_->entries.data();
  const S particleDrag = static_cast<S>(0.5 * wind_.airDensity * wind_.dragCoefficient * wind_.particleArea);
  for (Index t = 0; t < count; ++t) {
    const Index i = begin + t;
    S fx = 0, fy = 0, fz = 0;
    if (off[i + 1] > off[i]) {
      for (Index k = off[i]; k < off[i + 1]; ++k) {
        fx += Fx[inc[k]];
        fy += Fy[inc[k]];
        fz += Fz[inc[k]];
      }
    } else {  // on no triangle: quadratic drag 1/2 rho C_D A_p |u| u
      const S uu = std::sqrt(ux[i] * ux[i] + uy[i] * uy[i] + uz[i] * uz[i]);
      fx = particleDrag * uu * ux[i];
      fy = particleDrag * uu * uy[i];
      fz = particleDrag * uu * uz[i];
    }
    ax[t] += w[i] * fx;
    ay[t] += w[i] * fy;
    az[t] += w[i] * fz;
  }
}

template <class S>
Vec3d WindForce<S>::airVelocity(const Vec3d& x, double time) const {
  Vec3d u = wind_.velocity;
  for (int j = 0; j < modes_.count(); ++j) {
    const double s = portableSine(modes_.kx[j] * x.x + modes_.ky[j] * x.y + modes_.kz[j] * x.z +
                                  std::fmod(modes_.phase[j] - modes_.omega[j] * time, kTwoPi));
    u.x += modes_.ax[j] * s;
    u.y += modes_.ay[j] * s;
    u.z += modes_.az[j] * s;
  }
  return u;
}

template class WindForce<float>;
template class WindForce<double>;

}  // namespace weft::detail
