#include "visibility/ray_caster.h"

#include <algorithm>
#include <stdexcept>
#include <utility>

#include "visibility/shaft.h"
#include <vector>

namespace penumbra {

RayCaster::RayCaster(const Scene& scene) {
    device_ = rtcNewDevice("threads=1");  // the BVH build is small next to the solve; keep it serial
    if (!device_) throw std::runtime_error("Embree: could not create a device");
    scene_ = rtcNewScene(device_);
    std::vector<float> verts;
    std::vector<unsigned> tris;
    std::vector<Bounds> boxes;
    for (size_t pi = 0; pi < scene.polygons.size(); ++pi) {
        const ScenePolygon& p = scene.polygons[pi];
        if (!p.occludes) continue;
        Bounds box;
        for (int k = 0; k < p.geom.n; ++k) box.extend(p.geom.v[k]);
        boxes.push_back(box);
        occluderPolygon_.push_back(int(pi));
        unsigned base = unsigned(verts.size() / 3);
        for (int k = 0; k < p.geom.n; ++k) {
            verts.push_back(float(p.geom.v[k].x));
            verts.push_back(float(p.geom.v[k].y));
            verts.push_back(float(p.geom.v[k].z));
        }
        for (int k = 1; k + 1 < p.geom.n; ++k) {
            triPolygon_.push_back(int(pi));
            tris.push_back(base);
            tris.push_back(base + k);
            tris.push_back(base + k + 1);
        }
    }
    numTriangles_ = tris.size() / 3;
    occluders_ = BoxTree(std::move(boxes));
    auto attach = [&](RTCScene target, const std::vector<unsigned>& idx) {
        size_t count = idx.size() / 3;
        if (count == 0) return;
        RTCGeometry geom = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_TRIANGLE);
        float* vb = static_cast<float*>(rtcSetNewGeometryBuffer(
            geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), verts.size() / 3));
        unsigned* ib = static_cast<unsigned*>(rtcSetNewGeometryBuffer(
            geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), count));
        std::copy(verts.begin(), verts.end(), vb);
        std::copy(idx.begin(), idx.end(), ib);
        rtcCommitGeometry(geom);
        rtcAttachGeometry(target, geom);
        rtcReleaseGeometry(geom);
    };
    attach(scene_, tris);
    rtcCommitScene(scene_);
    // A second scene for lamps' shadow rays, only when some polygon lets them through (a separate scene
    // rather than ray masks, which an Embree build may leave out).
    std::vector<unsigned> lampTris;
    bool anyPassed = false;
    for (size_t t = 0; t < triPolygon_.size(); ++t) {
        if (scene.polygons[size_t(triPolygon_[t])].blocksLamps)
            lampTris.insert(lampTris.end(), tris.begin() + long(3 * t), tris.begin() + long(3 * t + 3));
        else
            anyPassed = true;
    }
    if (anyPassed) {
        lampScene_ = rtcNewScene(device_);
        numLampTriangles_ = lampTris.size() / 3;
        attach(lampScene_, lampTris);
        rtcCommitScene(lampScene_);
    }
    // And one for rays carrying reflected light, when some polygon is hidden from diffuse rays.
    std::vector<unsigned> diffuseTris;
    bool anyHidden = false;
    for (size_t t = 0; t < triPolygon_.size(); ++t) {
        if (scene.polygons[size_t(triPolygon_[t])].diffuseVisible)
            diffuseTris.insert(diffuseTris.end(), tris.begin() + long(3 * t), tris.begin() + long(3 * t + 3));
        else
            anyHidden = true;
    }
    if (anyHidden) {
        diffuseScene_ = rtcNewScene(device_);
        numDiffuseTriangles_ = diffuseTris.size() / 3;
        attach(diffuseScene_, diffuseTris);
        rtcCommitScene(diffuseScene_);
    }
}

RayCaster::~RayCaster() {
    if (lampScene_) rtcReleaseScene(lampScene_);
    if (diffuseScene_) rtcReleaseScene(diffuseScene_);
    if (scene_) rtcReleaseScene(scene_);
    if (device_) rtcReleaseDevice(device_);
}

bool RayCaster::shaftIsClear(const Bounds& a, const Bounds& b, int skipA, int skipB) const {
    return shaftIsClear(a, b, skipA, skipB, nullptr, 0, 0.0);
}

bool RayCaster::shaftIsClear(const Bounds& a, const Bounds& b, int skipA, int skipB, const HalfSpace* above,
                             int numAbove, double height) const {
    Shaft shaft(a, b);
    auto below = [&](const Bounds& box) {
        for (int k = 0; k < numAbove; ++k) {
            const Vec3& n = above[k].normal;
            // The box corner farthest along the normal.
            Vec3 far{n.x > 0 ? box.hi.x : box.lo.x, n.y > 0 ? box.hi.y : box.lo.y, n.z > 0 ? box.hi.z : box.lo.z};
            if (dot(n, far - above[k].point) < height) return true;
        }
        return false;
    };
    bool clear = true;
    occluders_.query(
        [&](const Bounds& node) { return clear && shaft.classify(node) != Shaft::Outside && !below(node); },
        [&](int i) {
            int p = occluderPolygon_[i];
            if (clear && p != skipA && p != skipB && shaft.classify(occluders_.box(i)) != Shaft::Outside &&
                !below(occluders_.box(i)))
                clear = false;
        });
    return clear;
}

RayCaster::Hit RayCaster::firstHit(const Vec3& origin, const Vec3& dir, double far) const {
    if (numTriangles_ == 0) return {};
    RTCRayHit rh{};
    rh.ray.org_x = float(origin.x); rh.ray.org_y = float(origin.y); rh.ray.org_z = float(origin.z);
    rh.ray.dir_x = float(dir.x); rh.ray.dir_y = float(dir.y); rh.ray.dir_z = float(dir.z);
    rh.ray.tnear = 0.0f;
    rh.ray.tfar = float(far);
    rh.ray.mask = 0xFFFFFFFF;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
#if PENUMBRA_EMBREE_MAJOR >= 4
    rtcIntersect1(scene_, &rh);
#else
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    rtcIntersect1(scene_, &ctx, &rh);
#endif
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return {};
    return {triPolygon_[rh.hit.primID], double(rh.ray.tfar)};
}

std::vector<char> RayCaster::buriedFaces(const Scene& scene, double lift) const {
    std::vector<char> out(scene.polygons.size(), 0);
    if (numTriangles_ == 0) return out;
    const double far = 4 * scene.diagonal;
    for (size_t i = 0; i < scene.polygons.size(); ++i) {
        const ScenePolygon& p = scene.polygons[i];
        if (!p.receives) continue;
        // Points near the corners too: a slab standing on the middle of a floor tile covers the centre and the
        // points halfway to the corners once it covers a quarter of the tile, and a tile taken for buried
        // gets no light from any cluster link though half of it is open (its ceiling's light: none of it).
        Vec3 c = p.geom.centroid(), pts[9];
        int n = 0;
        pts[n++] = c;
        for (int k = 0; k < p.geom.n && n < 9; ++k) pts[n++] = (c + p.geom.v[k]) * 0.5;
        for (int k = 0; k < p.geom.n && n < 9; ++k) pts[n++] = c + (p.geom.v[k] - c) * 0.95;
        bool inside = true;
        for (int k = 0; k < n && inside; ++k) inside = metFromBehind(scene, pts[k] + p.normal * lift, p.normal, far);
        out[i] = inside;
    }
    return out;
}

bool RayCaster::metFromBehind(const Scene& scene, const Vec3& origin, const Vec3& dir, double far) const {
    // Nothing met is open sky. A two-sided face's back copy follows its front and shares its triangles: met
    // from behind, they were the copy's front (a ceiling over a flipped two-sided floor was taken for buried,
    // and no cluster link lit it).
    Hit h = firstHit(origin, dir, far);
    if (h.polygon < 0) return false;
    size_t hp = size_t(h.polygon);
    return !hasBackCopy(scene.polygons, hp) && dot(scene.polygons[hp].normal, dir) > 0;
}

template <class Visit>
void RayCaster::forOccludersNear(const Scene& scene, size_t i, double lift, const bool& done, Visit&& visit) const {
    Bounds near = polygonBox(scene.polygons[i]);
    near.lo = near.lo - Vec3{lift, lift, lift};
    near.hi = near.hi + Vec3{lift, lift, lift};
    const size_t front = occluderOf(scene.polygons, i);
    occluders_.query([&](const Bounds& node) { return !done && overlaps(node, near); },
                     [&](int b) {
                         size_t q = size_t(occluderPolygon_[size_t(b)]);
                         if (done || q == front || !overlaps(occluders_.box(b), near)) return;
                         visit(q);
                     });
}

std::vector<char> RayCaster::touchedFaces(const Scene& scene, double lift) const {
    std::vector<char> out(scene.polygons.size(), 0);
    for (size_t i = 0; i < scene.polygons.size(); ++i) {
        const ScenePolygon& p = scene.polygons[i];
        const Vec3 origin = p.geom.v[0];
        bool touched = false;
        forOccludersNear(scene, i, lift, touched, [&](size_t q) {
            const ScenePolygon& sq = scene.polygons[q];
            for (int k = 0; k < sq.geom.n && !touched; ++k) touched = dot(sq.geom.v[k] - origin, p.normal) > lift;
        });
        out[i] = touched;
    }
    return out;
}

namespace {

// Whether the segment [a, b] in p's plane runs through p's interior at more than `inset` from its edges, for
// a convex p counter-clockwise around its normal.
bool crossesInterior(const ScenePolygon& p, const Vec3& a, const Vec3& b, double inset) {
    double t0 = 0, t1 = 1;
    const Vec3 d = b - a;
    for (int j = 0; j < p.geom.n; ++j) {
        const Vec3& v0 = p.geom.v[size_t(j)];
        const Vec3& v1 = p.geom.v[size_t((j + 1) % p.geom.n)];
        const Vec3 m = normalize(cross(p.normal, v1 - v0));  // inward
        const double f = dot(a - v0, m) - inset, fd = dot(d, m);
        if (fd > 0)
            t0 = std::max(t0, -f / fd);
        else if (fd < 0)
            t1 = std::min(t1, -f / fd);
        else if (f < 0)
            return false;
        if (t0 >= t1) return false;
    }
    return (t1 - t0) * length(d) > inset;
}

bool isConvex(const ScenePolygon& p) {
    for (int j = 0; j < p.geom.n; ++j) {
        const Vec3& v0 = p.geom.v[size_t(j)];
        const Vec3& v1 = p.geom.v[size_t((j + 1) % p.geom.n)];
        const Vec3& v2 = p.geom.v[size_t((j + 2) % p.geom.n)];
        if (dot(cross(v1 - v0, v2 - v1), p.normal) < 0) return false;
    }
    return true;
}

}  // namespace

std::vector<char> RayCaster::footprintFaces(const Scene& scene, double lift, const std::vector<char>& touched) const {
    std::vector<char> out = touched;
    for (size_t i = 0; i < scene.polygons.size(); ++i) {
        const ScenePolygon& p = scene.polygons[i];
        if (!out[i] || !isConvex(p)) continue;
        const Vec3 origin = p.geom.v[0];
        bool found = false;
        forOccludersNear(scene, i, lift, found, [&](size_t q) {
            // Where q meets p's plane: its corners in the plane and its edges' crossings.
            const Polygon& g = scene.polygons[q].geom;
            Vec3 meet[2 * Polygon::kMaxVerts];
            int m = 0;
            bool inFront = false;
            for (int k = 0; k < g.n; ++k) {
                const Vec3& a = g.v[size_t(k)];
                const Vec3& c = g.v[size_t((k + 1) % g.n)];
                const double da = dot(a - origin, p.normal), dc = dot(c - origin, p.normal);
                inFront |= da > lift;
                if (std::fabs(da) <= lift) meet[m++] = a;
                if ((da > lift && dc < -lift) || (da < -lift && dc > lift)) meet[m++] = a + (c - a) * (da / (da - dc));
            }
            if (!inFront || m < 2) return;
            // A plane meets a convex polygon along one segment: between its two farthest points.
            int x0 = 0, x1 = 1;
            double far = -1;
            for (int x = 0; x < m; ++x)
                for (int y = x + 1; y < m; ++y)
                    if (length2(meet[x] - meet[y]) > far) far = length2(meet[x] - meet[y]), x0 = x, x1 = y;
            found = crossesInterior(p, meet[x0], meet[x1], lift);
        });
        out[i] = found;
    }
    return out;
}

std::vector<int> RayCaster::occludersInShaft(const Shaft& shaft) const {
    std::vector<int> out;
    occluders_.query([&](const Bounds& node) { return shaft.classify(node) != Shaft::Outside; },
                     [&](int i) {
                         if (shaft.classify(occluders_.box(i)) != Shaft::Outside) out.push_back(occluderPolygon_[i]);
                     });
    return out;
}

namespace {

// Casts the n segments segment(k) = (origin, target) as 16-wide coherent occlusion packets (a link's
// or a bake point's rays start close together and end close together: measured 2.4x faster than
// single rays here) and reports each one's visibility to visible(k, bool).
template <class Segment, class Visible>
void castPackets(RTCScene scene, int n, Segment segment, Visible visible) {
    // Embree 4 moved the coherence hint from the intersect context to the query arguments.
#if PENUMBRA_EMBREE_MAJOR >= 4
    RTCOccludedArguments args;
    rtcInitOccludedArguments(&args);
    args.flags = RTC_RAY_QUERY_FLAG_COHERENT;
#else
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
#endif
    for (int base = 0; base < n; base += 16) {
        alignas(64) RTCRay16 rays;
        alignas(64) int valid[16];
        for (int i = 0; i < 16; ++i) {
            int k = base + i;
            valid[i] = k < n ? -1 : 0;
            Vec3 o, d{0, 0, 1};
            if (k < n) {
                auto [from, to] = segment(k);
                o = from;
                d = to - from;
            }
            rays.org_x[i] = float(o.x); rays.org_y[i] = float(o.y); rays.org_z[i] = float(o.z);
            rays.dir_x[i] = float(d.x); rays.dir_y[i] = float(d.y); rays.dir_z[i] = float(d.z);
            rays.tnear[i] = 0.0f;
            rays.tfar[i] = 1.0f;
            rays.time[i] = 0.0f;
            rays.mask[i] = 0xFFFFFFFF;
            rays.id[i] = 0;
            rays.flags[i] = 0;
        }
#if PENUMBRA_EMBREE_MAJOR >= 4
        rtcOccluded16(valid, scene, &rays, &args);
#else
        rtcOccluded16(valid, scene, &ctx, &rays);
#endif
        for (int i = 0; i < 16 && base + i < n; ++i) visible(base + i, rays.tfar[i] >= 0.0f);
    }
}

}  // namespace

void RayCaster::visibleMask(const Vec3& from, const Vec3* to, int n, char* visible, bool lampRay) const {
    const bool lamp = lampRay && lampScene_;
    if ((lamp ? numLampTriangles_ : numTriangles_) == 0) {
        std::fill(visible, visible + std::max(n, 0), char(1));
        return;
    }
    castPackets(lamp ? lampScene_ : scene_, n, [&](int k) { return std::make_pair(from, to[k]); },
                [&](int k, bool v) { visible[k] = v ? 1 : 0; });
}

void RayCaster::visiblePairs(const Vec3* from, const Vec3* to, int n, char* visible, bool diffuseRay) const {
    const bool diffuse = diffuseRay && diffuseScene_;
    if ((diffuse ? numDiffuseTriangles_ : numTriangles_) == 0) {
        std::fill(visible, visible + std::max(n, 0), char(1));
        return;
    }
    castPackets(diffuse ? diffuseScene_ : scene_, n, [&](int k) { return std::make_pair(from[k], to[k]); },
                [&](int k, bool v) { visible[k] = v ? 1 : 0; });
}

}  // namespace penumbra
