#include "bake/lights.h"

#include <algorithm>
#include <atomic>
#include <cmath>

#include "util/parallel.h"
#include "util/seed.h"
#include "util/sobol.h"

namespace penumbra {
namespace {

// Two unit vectors completing w to an orthonormal frame.
void frame(const Vec3& w, Vec3& t1, Vec3& t2) {
    Vec3 a = std::fabs(w.x) < 0.6 ? Vec3{1, 0, 0} : Vec3{0, 1, 0};
    t1 = normalize(cross(w, a));
    t2 = cross(w, t1);
}

// Sample k of `count` on the unit disk: the Sobol' net, shifted off the disk's centre and edge by half
// a cell and by `shift` (toroidally), mapped by area (radius sqrt(u)).
void diskPoint(int k, int count, const double shift[2], double& x, double& y) {
    double u = std::fmod(sobol(uint32_t(k), 0) + 0.5 / count + shift[0], 1.0);
    double v = std::fmod(sobol(uint32_t(k), 1) + 0.5 / count + shift[1], 1.0);
    double r = std::sqrt(u), phi = 2 * M_PI * v;
    x = r * std::cos(phi);
    y = r * std::sin(phi);
}

int powerOfTwoBelow(int n) {
    while (n & (n - 1)) n &= n - 1;
    return std::max(n, 1);
}

// Sample points for a lamp that looks `size` (radians, or diameter over distance) wide: a nearly
// point-like lamp casts nearly hard shadows, which a few points resolve.
int samplesFor(int maxRays, double size) {
    int n = int(std::ceil(maxRays * std::min(1.0, 2.0 * size)));
    return powerOfTwoBelow(std::clamp(n, std::min(4, maxRays), maxRays));
}

}  // namespace

double spotAttenuation(const Light& l, double cosAxis) {
    double cosEdge = std::cos(0.5 * l.spotSize);
    if (cosAxis <= cosEdge) return 0;
    double smooth = (1 - cosEdge) * l.spotBlend, t = cosAxis - cosEdge;
    double a = l.spotCosine ? cosAxis : 1.0;
    if (smooth > 0 && t < smooth) {
        double u = t / smooth;
        a *= u * u * (3 - 2 * u);
    }
    return a;
}

Rgb envRadiance(const Light& l, const Vec3& d) {
    // Cycles' equirectangular mapping: u from the azimuth (0.5 looking along +X, 0.25 along +Y), v from
    // the elevation (0 straight down, 1 straight up); the nearest pixel (Cycles' Linear interpolation
    // would blend four; the irradiance integral does not see the difference at map resolutions).
    double u = -std::atan2(d.y, d.x) / (2 * M_PI) + 0.5;
    double v = std::atan2(d.z, std::hypot(d.x, d.y)) / M_PI + 0.5;
    int x = std::clamp(int(u * l.envWidth), 0, l.envWidth - 1);
    int y = std::clamp(int(v * l.envHeight), 0, l.envHeight - 1);
    const float* px = l.env.data() + (size_t(y) * size_t(l.envWidth) + size_t(x)) * 3;
    return {px[0], px[1], px[2]};
}

double sunDiskFactor(double angle) {
    double t = std::tan(0.5 * std::min(angle, M_PI * (179.0 / 180.0)));
    if (t < 1e-4) return 1 - 0.25 * t * t;  // the series: the closed form cancels badly here
    return 2 * (std::sqrt(1 + t * t) - 1) / (t * t);
}

namespace {

// A point or spot lamp that Cycles 4.0+ draws as a sphere of radius r and uniform radiance
// L = P / (4 pi^2 r^2) (Soft Falloff off). From outside, the sphere fills the cone of half-angle a,
// sin a = r / d, about the direction to its centre; wholly above the horizon its irradiance is
// pi L sin^2 a cos = P cos / (4 pi d^2), the bare point's. The sample directions are spread evenly over
// that cone's solid angle, so where the cone crosses the horizon or a spot's edge (Cycles weighs each
// direction by the spot's smoothstep, not the centre's) their mean is the integral itself.
template <class ClearWeight>
Rgb sphereLamp(const Light& l, const Vec3& p, const Vec3& n, double d2, const Vec3& dir, int maxRays,
               const double shift[2], bool shadows, ClearWeight& clearWeight, Vec3* to, double* w) {
    const double r = l.radius, d = std::sqrt(d2);
    const Rgb L = l.value / (4 * M_PI * M_PI * r * r);
    const bool spot = l.type == LightType::Spot;
    // Inside the sphere every direction meets it, and Cycles applies no spot cone there.
    if (d <= r) return L * M_PI;
    const double sinA = r / d, cosA = std::sqrt(std::max(0.0, 1 - sinA * sinA));
    const double cosR = dot(dir, n);
    if (cosR <= -sinA) return {};
    if (!spot && cosR >= sinA && !shadows) return l.value * (cosR / (4 * M_PI * d2));
    const double solidAngle = 2 * M_PI * (1 - cosA);
    int count = samplesFor(maxRays, 2 * sinA);
    Vec3 t1, t2;
    frame(dir, t1, t2);
    double cosSum = 0;
    for (int k = 0; k < count; ++k) {
        double x, y;
        diskPoint(k, count, shift, x, y);
        // The disk's area measure onto the cap's solid angle: u = x^2 + y^2 spreads 1 - cos evenly.
        double u = x * x + y * y, rho = std::sqrt(u);
        double cg = 1 - u * (1 - cosA), sg = std::sqrt(std::max(0.0, 1 - cg * cg));
        double cx = rho > 0 ? x / rho : 1, cy = rho > 0 ? y / rho : 0;
        Vec3 om = dir * cg + (t1 * cx + t2 * cy) * sg;
        double c = std::max(0.0, dot(om, n));
        double att = spot ? spotAttenuation(l, -dot(om, l.direction)) : 1.0;
        // The near side of the sphere along om (law of cosines), where the shadow ray ends.
        double t = d * cg - std::sqrt(std::max(0.0, r * r - d2 * sg * sg));
        to[k] = p + om * t;
        w[k] = c * att;
        cosSum += c;
    }
    if (!(cosSum > 0)) return {};
    double seen = clearWeight(count);
    if (!spot && cosR >= sinA) return l.value * (cosR / (4 * M_PI * d2) * seen / cosSum);
    return L * (solidAngle * seen / count);
}

}  // namespace

LightSet::LightSet(const Scene& sc, const RayCaster* rays, int maxRays, int seed)
    : sc_(sc), rays_(rays), maxRays_(powerOfTwoBelow(std::clamp(maxRays, 1, kMaxRays))), seed_(seed) {
    seedShift(seed, shift_);
    lift_ = 1e-5 * sc.diagonal;
    far_ = 4 * sc.diagonal;
}

Rgb LightSet::irradiance(const Vec3& p, const Vec3& n, int maxRays, LightStats* stats) const {
    return irradiance(p, n, maxRays, shift_, stats);
}

Rgb LightSet::irradiance(const Vec3& p, const Vec3& n, int maxRays, const double shift[2], LightStats* stats) const {
    return irradianceOn(-1, p, n, maxRays, shift, stats);
}

Rgb LightSet::irradianceOn(int polygon, const Vec3& p, const Vec3& n) const {
    return irradianceOn(polygon, p, n, -1, shift_, nullptr);
}

Rgb LightSet::irradianceOn(int polygon, const Vec3& p, const Vec3& n, int maxRays, const double shift[2],
                           LightStats* stats) const {
    int m = maxRays < 0 ? maxRays_ : powerOfTwoBelow(std::clamp(maxRays, 1, kMaxRays));
    Rgb sum;
    for (size_t i = 0; i < sc_.lights.size(); ++i) sum += one(sc_.lights[i], int(i), polygon, p, n, m, shift, stats);
    return sum;
}

Rgb LightSet::one(const Light& l, int index, int polygon, const Vec3& p, const Vec3& n, int maxRays,
                  const double shift[2], LightStats* stats) const {
    const bool shadows = rays_ && l.castShadow;
    const Vec3 from = p + n * lift_;
    // Per thread, allocated once: arrays of kMaxRays Vec3 on the stack would be zeroed (Vec3's
    // initialisers) for every light at every texel.
    struct Scratch {
        std::vector<Vec3> to = std::vector<Vec3>(kMaxRays);
        std::vector<double> w = std::vector<double>(kMaxRays);
        std::vector<char> clear = std::vector<char>(kMaxRays);
    };
    thread_local Scratch scratch;
    Vec3* to = scratch.to.data();
    double* w = scratch.w.data();
    char* clear = scratch.clear.data();
    // Sum of w over the points whose segment from `from` is clear. With `shortcut` the first few points
    // decide: when they all agree (full light, umbra) the rest are taken to agree too.
    // Point, spot and sun lamps cast shadow rays in Cycles, which objects hidden from them let through.
    const bool lampRay = l.type != LightType::World;
    auto clearWeight = [&](int count, bool shortcut = true) {
        double all = 0, seen = 0;
        for (int k = 0; k < count; ++k) all += w[k];
        if (!shadows) return all;
        int coarse = shortcut ? std::min(count, 8) : count;
        rays_->visibleMask(from, to, coarse, clear, lampRay);
        int hits = 0;
        for (int k = 0; k < coarse; ++k) hits += clear[k];
        if (count > coarse) {
            if (hits == 0 || hits == coarse) std::fill(clear + coarse, clear + count, char(hits ? 1 : 0));
            else rays_->visibleMask(from, to + coarse, count - coarse, clear + coarse, lampRay);
        }
        if (stats) stats->rays += size_t(hits == 0 || hits == coarse ? coarse : count);
        for (int k = 0; k < count; ++k) seen += clear[k] ? w[k] : 0.0;
        return seen;
    };

    switch (l.type) {
        case LightType::Point:
        case LightType::Spot: {
            Vec3 d = l.position - p;
            double d2 = length2(d);
            if (!(d2 > 0)) return {};
            Vec3 dir = d / std::sqrt(d2);
            double cosR = dot(dir, n);
            bool spot = l.type == LightType::Spot;
            if (l.sphere && l.radius > 0) return sphereLamp(l, p, n, d2, dir, maxRays, shift, shadows, clearWeight, to, w);
            if (cosR <= 0) return {};
            // Cycles' disk of radius r facing the point, of radiance P / (4 pi^2 r^2): its irradiance
            // along the axis is P / (4 pi (d^2 + r^2)), and by symmetry cos times that on a tilted
            // receiver while the disk stays above the receiver's horizon.
            Rgb E = l.value * (cosR / (4 * M_PI * (d2 + l.radius * l.radius)));
            if (l.radius <= 0) {
                w[0] = spot ? spotAttenuation(l, -dot(dir, l.direction)) : 1.0;
                if (w[0] <= 0) return {};
                to[0] = l.position;
                return E * clearWeight(1);
            }
            if (!shadows && !spot) return E;
            if (!spot && sunTextures_) {
                // A face with a texture (sun_textures.h) sees the whole disk; V is its visible share by area,
                // as the points below count it.
                double v = sunTextures_->visibility(index, polygon, p);
                if (std::isfinite(v)) return E * v;
            }
            int count = samplesFor(maxRays, 2 * l.radius / std::sqrt(d2));
            Vec3 t1, t2;
            frame(dir, t1, t2);
            for (int k = 0; k < count; ++k) {
                double x, y;
                diskPoint(k, count, shift, x, y);
                to[k] = l.position + (t1 * x + t2 * y) * l.radius;
                if (!spot) {
                    w[k] = 1.0;
                    continue;
                }
                // A spot weighs each point of the disk by the cone at its own direction, which breaks the
                // symmetry the closed form rests on: each point carries its own share of the disk's
                // irradiance, L (pi r^2 / count) cos_receiver cos_disk / t^2 with L = P / (4 pi^2 r^2).
                // (The centre's cosine times the mean cone weight was 4 % low 30 degrees off the axis of
                // a Cycles 3.4 spot of radius 0.5 m at 1 m, 20 % at 55.)
                Vec3 v = p - to[k];
                double t2k = length2(v);
                Vec3 u = v / std::sqrt(t2k);
                double cosRec = std::max(0.0, -dot(u, n)), cosDisk = -dot(u, dir);
                w[k] = cosRec * cosDisk * spotAttenuation(l, dot(u, l.direction)) / (4 * M_PI * count * t2k);
            }
            if (spot) return l.value * clearWeight(count);
            return E * (clearWeight(count) / count);
        }
        case LightType::Sun: {
            Vec3 w0 = -l.direction;
            double c0 = dot(w0, n);
            if (l.angle <= 0) {
                if (c0 <= 0) return {};
                to[0] = from + w0 * far_;
                w[0] = 1;
                return l.value * (c0 * clearWeight(1));
            }
            double t = std::tan(0.5 * std::min(l.angle, M_PI * (179.0 / 180.0)));
            double sinEdge = t / std::sqrt(1 + t * t);  // of the disk's angular radius
            if (c0 <= -sinEdge) return {};
            if (sunTextures_ && shadows) {
                // A face with a texture sees the whole disk above its horizon (sun_textures.h), where the
                // closed form holds; V is the cosine-weighted visible share.
                double v = sunTextures_->visibility(index, polygon, p);
                if (std::isfinite(v)) return l.value * (sunDiskFactor(l.angle) * c0 * v);
            }
            int count = samplesFor(maxRays, l.angle);
            Vec3 t1, t2;
            frame(w0, t1, t2);
            double axial = 0, cosSum = 0;
            for (int k = 0; k < count; ++k) {
                double x, y;
                diskPoint(k, count, shift, x, y);
                Vec3 dir = normalize(w0 + (t1 * x + t2 * y) * t);
                to[k] = from + dir * far_;
                w[k] = std::max(0.0, dot(dir, n));
                axial += dot(dir, w0);
                cosSum += w[k];
            }
            double f = sunDiskFactor(l.angle);
            if (!(cosSum > 0)) return {};
            double seen = clearWeight(count);
            // Wholly above the horizon the closed form holds (f cos); the points give only the
            // visible share. Across the horizon the points give the clipped integral too.
            if (c0 >= sinEdge) return l.value * (f * c0 * seen / cosSum);
            return l.value * (f * seen / axial);
        }
        case LightType::World: {
            // Cosine-weighted directions: every clear one carries pi L / count.
            int count = maxRays;
            if (!shadows && l.env.empty()) return l.value * M_PI;
            Vec3 t1, t2;
            frame(n, t1, t2);
            for (int k = 0; k < count; ++k) {
                double x, y;
                diskPoint(k, count, shift, x, y);
                double z = std::sqrt(std::max(0.0, 1 - x * x - y * y));
                to[k] = from + (t1 * x + t2 * y + n * z) * far_;
                w[k] = 1;
            }
            // Every direction is cast: a wall low on the horizon can hide a few percent of the sky from
            // every one of eight points (5.6 % at twice the wall's height away).
            if (l.env.empty()) return l.value * (M_PI * clearWeight(count, false) / count);
            // An environment: every clear direction carries pi L(direction) / count. Fixed directions see
            // a map's detail unevenly; the irradiance of a smooth sky (what light through a window is)
            // is what this resolves, a small bright sun in the map is not.
            clearWeight(count, false);  // fills `clear` when there are shadows
            Rgb sum;
            for (int k = 0; k < count; ++k)
                if (!shadows || clear[k]) sum += envRadiance(l, normalize(to[k] - from));
            return mul(l.value, sum) * (M_PI / count);
        }
    }
    return {};
}

Rgb LightSet::elementIrradiance(const Element& e, const Vec3& n, LightStats* stats) const {
    // Sixteen points of equal area (a 4 x 4 grid; on triangles the centroids of the 16 triangles of its
    // fourfold subdivision), not the refiner's four Gauss points: an element a sun patch or a hard
    // shadow crosses reflects the lit part of it, and four points read that part in quarters.
    Vec3 pts[16];
    int np = 0;
    if (e.n == 4) {
        for (int i = 0; i < 4; ++i)
            for (int j = 0; j < 4; ++j) pts[np++] = e.pointAt((i + 0.5) / 4, (j + 0.5) / 4);
    } else {
        for (int i = 0; i < 4; ++i)
            for (int j = 0; i + j < 4; ++j) {
                pts[np++] = e.pointAt((i + 1.0 / 3) / 4, (j + 1.0 / 3) / 4);
                if (i + j < 3) pts[np++] = e.pointAt((i + 2.0 / 3) / 4, (j + 2.0 / 3) / 4);
            }
    }
    // Each point turns the Sobol' set by its own fixed offset: with one set for all, every element of a
    // wall saw the sky through a window along the same 16 directions, and the room came out 2.8 %
    // darker than Cycles (0.7 % with 256 directions; 0.65 % with 4 x 32 turned ones, the Cycles
    // reference's own noise being 1.1 % per face). The element's directions are shared among its points.
    int m = std::max(1, std::min(maxRays_, 32) / 4);
    Rgb sum;
    for (int k = 0; k < np; ++k) {
        uint64_t h = (seeded(e.key, seed_) + uint64_t(k) + 1) * 0x9E3779B97F4A7C15ull;
        h ^= h >> 29;
        h *= 0xBF58476D1CE4E5B9ull;
        h ^= h >> 32;
        double shift[2] = {double(h & 0xFFFFFFFFu) / 4294967296.0, double(h >> 32) / 4294967296.0};
        sum += irradianceOn(e.polygon, pts[k], n, m, shift, stats);
    }
    return sum / double(np);
}

std::vector<Rgb> LightSet::leafIrradiance(const Hierarchy& h, int threads, LightStats* stats) const {
    std::vector<Rgb> out(h.size());
    if (empty()) return out;
    std::atomic<size_t> rays{0};
    parallelFor(h.size(), threads, 256, [&](size_t b, size_t e, int) {
        LightStats local;
        for (size_t i = b; i < e; ++i) {
            const Element& el = h[i];
            const ScenePolygon& p = sc_.polygons[size_t(el.polygon)];
            if (!el.isLeaf() || !p.receives) continue;
            out[i] = elementIrradiance(el, p.normal, &local);
        }
        rays += local.rays;
    });
    if (stats) stats->rays += rays;
    return out;
}

}  // namespace penumbra
