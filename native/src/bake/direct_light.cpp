#include "bake/direct_light.h"

#include <algorithm>
#include <cmath>

#include "geometry/form_factor.h"
#include "util/seed.h"
#include "util/sobol.h"

namespace penumbra {
namespace {

// Point at (s, t) in [0,1]^2 on a (possibly warped) quad, bilinear, or on a triangle, collapsing the
// square's s = 0 edge onto v0; `jac` is the density of area per unit (s, t), up to a constant.
Vec3 pointOn(const Polygon& g, double s, double t, double& jac) {
    if (g.n == 4) {
        jac = 1;
        return g.v[0] * ((1 - s) * (1 - t)) + g.v[1] * (s * (1 - t)) + g.v[2] * (s * t) + g.v[3] * ((1 - s) * t);
    }
    jac = s;
    return g.v[0] * (1 - s) + (g.v[1] * (1 - t) + g.v[2] * t) * s;
}

}  // namespace

DirectLight::DirectLight(const Scene& sc, const RayCaster& rays, int maxRays,
                         std::vector<std::vector<int>> excluded, int seed)
    : sc_(sc), rays_(rays), excluded_(std::move(excluded)) {
    maxRays_ = std::clamp(maxRays, 0, 256);
    seedShift(seed, shift_);
    lift_ = 1e-5 * sc.diagonal;
    for (size_t i = 0; i < sc.polygons.size(); ++i) {
        const ScenePolygon& p = sc.polygons[i];
        if (!(maxComponent(p.emission) > 0)) continue;
        int occluder = int(occluderOf(sc.polygons, i));
        Emitter* group = nullptr;
        for (Emitter& e : emitters_) {
            const ScenePolygon& q = sc.polygons[size_t(e.polygons[0])];
            if (q.object == p.object && q.castsShadow == p.castsShadow && e.polygons.size() < 64 && q.emission.x == p.emission.x &&
                q.emission.y == p.emission.y && q.emission.z == p.emission.z && dot(q.normal, p.normal) > 1 - 1e-9 &&
                std::fabs(dot(p.geom.v[0] - q.geom.v[0], q.normal)) <= 1e-6 * sc.diagonal) {
                group = &e;
                break;
            }
        }
        if (!group) {
            emitters_.emplace_back();
            group = &emitters_.back();
            group->normal = p.normal;
            group->E = p.emission;
            group->castsShadow = p.castsShadow;
        }
        group->polygons.push_back(int(i));
        group->occluders.push_back(occluder);
        group->geoms.push_back(p.geom);
        Vec3 c = p.geom.centroid();
        double r = 0;
        for (int k = 0; k < p.geom.n; ++k) r = std::max(r, length(p.geom.v[k] - c));
        group->centers.push_back(c);
        group->areas.push_back(p.area);
        group->sizes.push_back(r);
        group->area += p.area;
        for (int k = 0; k < p.geom.n; ++k) group->box.extend(p.geom.v[k]);
    }
    for (Emitter& e : emitters_) {
        e.center = e.box.center();
        e.size = length(e.box.diagonal());
    }
}

double DirectLight::visibility(const Emitter& e, const Vec3& p, const Vec3& n, const Vec3& from, int count,
                               DirectStats* stats) const {
    Vec3 to[256];
    double w[256];
    char hit[256];
    // `count` points in all, shared among the group's faces. They are the 2-D Sobol' sequence, the
    // same for every bake point: its first 2^k points are stratified in both coordinates and in every
    // elementary box of area 2^-k, so a straight shadow edge of any direction is crossed in about
    // `count` steps, where a regular grid of m x m points crosses one in m, and there is no aliasing
    // with a regular blocker such as a lattice shade. Nested: the first points are the coarse set.
    int faces = int(e.geoms.size());
    int per = std::max(1, count / faces);
    int total = 0;
    const Vec3 lift = e.normal * lift_;
    double wsum = 0;
    for (const Polygon& g : e.geoms) {
        double cell = g.area() / per;
        for (int k = 0; k < per && total < 256; ++k) {
            double s = std::fmod(sobol(uint32_t(k), 0) + 0.5 / per + shift_[0], 1.0);
            double t = std::fmod(sobol(uint32_t(k), 1) + 0.5 / per + shift_[1], 1.0);
            double jac;
            Vec3 q = pointOn(g, s, t, jac);
            if (g.n == 3) jac *= 2;  // the triangle's mapping covers it with density 2s
            to[total] = q + lift;
            Vec3 dir = q - p;
            double r2 = length2(dir);
            // The point's share of the form factor: cos * cos / r^2 times its cell's area.
            double c = r2 > 0 ? std::max(0.0, dot(dir, n)) * std::max(0.0, -dot(dir, e.normal)) / (r2 * r2) : 0.0;
            w[total] = c * jac * cell;
            wsum += w[total];
            ++total;
        }
    }
    // Shadow rays, as Cycles' rays to a light sample are: an object with Ray Visibility > Shadow off
    // (kNoLampShadow) lets them through, here as for point, spot and sun lamps. Cycles agrees exactly
    // when the light's Multiple Importance is off; with it on (the default) its BSDF-sampled share
    // still meets the object (a card halfway under an area light: 4.5 % darker than passing through).
    rays_.visibleMask(from, to, total, hit, /*lampRay=*/true);
    if (stats) stats->rays += size_t(total);
    double vis = 0;
    if (wsum > 0) {
        for (int k = 0; k < total; ++k) vis += hit[k] ? w[k] : 0.0;
        return vis / wsum;
    }
    for (int k = 0; k < total; ++k) vis += hit[k] ? 1.0 : 0.0;
    return vis / total;
}

Rgb DirectLight::irradiance(const Vec3& p, const Vec3& n, int receiver, DirectStats* stats) const {
    Rgb sum;
    static const std::vector<int> none;
    const std::vector<int>& skip =
        receiver >= 0 && size_t(receiver) < excluded_.size() ? excluded_[size_t(receiver)] : none;
    const Vec3 from = p + n * lift_;
    for (const Emitter& e : emitters_) {
        // Some of it must face p.
        if (dot(p - e.center, e.normal) <= 0 && dot(p - e.box.lo, e.normal) <= 0 && dot(p - e.box.hi, e.normal) <= 0)
            continue;
        double F = 0;
        for (size_t k = 0; k < e.polygons.size(); ++k) {
            int q = e.polygons[k];
            if (q == receiver || (!skip.empty() && std::binary_search(skip.begin(), skip.end(), q))) continue;
            if (dot(p - e.geoms[k].v[0], e.normal) <= 0) continue;
            // A face small against its distance (r/d < 0.05) is a point source to second order in r/d,
            // and then costs no clipping or arc tangents.
            Vec3 d = e.centers[k] - p;
            double d2 = length2(d);
            if (e.sizes[k] * e.sizes[k] < 0.0025 * d2) {
                double c = std::max(0.0, dot(d, n)) * std::max(0.0, -dot(d, e.normal));
                F += e.areas[k] * c / (M_PI * d2 * d2);
            } else {
                F += pointToPolygonFormFactor(p, n, e.geoms[k]);
            }
        }
        if (!(F > 0)) continue;
        if (stats) ++stats->pairs;
        if (maxRays_ == 0 || !e.castsShadow) {
            sum += e.E * F;
            continue;
        }
        // Points grow with the emitter's angular size: a lamp far away needs few, one beside the
        // point many, or its penumbra would come out in coarse steps. A coarse set goes first; only
        // where it sees the emitter partly hidden are the rest cast (rays here cost less than a shaft
        // test would: on the Cornell box, shaft culling took 28 % of the bake, rays 3 %).
        double d = std::max(length(e.center - p), 1e-12);
        int count = std::clamp(int(std::ceil(maxRays_ * std::min(1.0, 2.0 * e.size / d))), std::min(4, maxRays_), maxRays_);
        while (count & (count - 1)) count &= count - 1;  // a power of two: a whole Sobol' net
        int coarse = std::min(count, 16);
        double vis = visibility(e, p, n, from, coarse, stats);
        if (count > coarse && vis > 0 && vis < 1) vis = visibility(e, p, n, from, count, stats);
        else if (stats && vis >= 1) ++stats->seenWhole;
        sum += e.E * (F * vis);
    }
    return sum;
}

}  // namespace penumbra
