#include "scene/scene.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <unordered_map>
#include <sstream>

#include "util/error.h"

namespace penumbra {
namespace {

std::string objectName(const SceneInput& in, size_t poly) {
    int o = in.objectIndex ? in.objectIndex[poly] : -1;
    if (o >= 0 && size_t(o) < in.objectNames.size()) return "'" + in.objectNames[o] + "'";
    return "#" + std::to_string(o);
}

[[noreturn]] void fail(const SceneInput& in, size_t poly, const std::string& what) {
    std::ostringstream s;
    s << "object " << objectName(in, poly) << " (face " << poly << "): " << what;
    throw InputError(s.str());
}

// Past this distance from the origin float32 input is coarser than 8 m, and a single far vertex makes
// every other face numerically zero-area at the scene's scale: it is a broken modifier or transform.
constexpr double kMaxCoordinate = 1e8;

Vec3 vertex(const SceneInput& in, int32_t i) {
    const float* p = in.vertices + size_t(i) * 3;
    return {p[0], p[1], p[2]};
}

// Splits a quad into two triangles along the diagonal whose halves both face the quad's normal.
void splitQuad(const Polygon& q, Polygon& t0, Polygon& t1) {
    Vec3 n = q.areaVector();
    auto tri = [](const Vec3& a, const Vec3& b, const Vec3& c) {
        Polygon p;
        p.push(a); p.push(b); p.push(c);
        return p;
    };
    Polygon a0 = tri(q.v[0], q.v[1], q.v[2]), a1 = tri(q.v[0], q.v[2], q.v[3]);
    if (dot(a0.areaVector(), n) > 0 && dot(a1.areaVector(), n) > 0) {
        t0 = a0; t1 = a1;
    } else {
        t0 = tri(q.v[0], q.v[1], q.v[3]);
        t1 = tri(q.v[1], q.v[2], q.v[3]);
    }
}

bool planarConvexQuad(const Polygon& q) {
    Vec3 n = q.normal();
    double size = std::sqrt(q.area());
    for (int i = 0; i < 4; ++i) {
        if (std::fabs(dot(q.v[i] - q.v[0], n)) > 1e-4 * size) return false;  // warped
        Vec3 e0 = q.v[(i + 1) % 4] - q.v[i], e1 = q.v[(i + 2) % 4] - q.v[(i + 1) % 4];
        if (dot(cross(e0, e1), n) <= 0) return false;  // reflex or degenerate corner
    }
    return true;
}

}  // namespace

Scene buildScene(const SceneInput& in) {
    Scene scene;
    scene.objectNames = in.objectNames;
    if (in.numPolygons == 0) throw InputError("nothing to bake: the scene has no faces");
    if (!in.vertices || !in.polygons || !in.reflectance || !in.emission || !in.flags || !in.objectIndex)
        throw InputError("internal: missing input array");

    // Pass 1: validate every face and find the bounds of what is referenced.
    Bounds raw;
    for (size_t p = 0; p < in.numPolygons; ++p) {
        const int32_t* idx = in.polygons + p * 4;
        int nv = idx[3] < 0 ? 3 : 4;
        if (in.objectIndex[p] < 0 || size_t(in.objectIndex[p]) >= in.objectNames.size())
            throw InputError("face " + std::to_string(p) + ": object_index " + std::to_string(in.objectIndex[p]) +
                             " is out of range [0, " + std::to_string(in.objectNames.size()) + ")");
        if (idx[3] < -1) fail(in, p, "negative vertex index " + std::to_string(idx[3]));
        for (int k = 0; k < nv; ++k) {
            if (idx[k] < 0 || size_t(idx[k]) >= in.numVertices)
                fail(in, p, "vertex index " + std::to_string(idx[k]) + " out of range [0, " +
                                std::to_string(in.numVertices) + ")");
            Vec3 v = vertex(in, idx[k]);
            if (!isFinite(v)) fail(in, p, "vertex " + std::to_string(idx[k]) + " is NaN or infinite");
            if (maxComponent(vmax(v, -v)) > kMaxCoordinate) {
                std::ostringstream s;
                s << "vertex " << idx[k] << " at (" << v.x << ", " << v.y << ", " << v.z
                  << ") is more than " << kMaxCoordinate << " m from the origin (a broken modifier or transform?)";
                fail(in, p, s.str());
            }
            raw.extend(v);
        }
        if (in.minEdge && (!std::isfinite(in.minEdge[p]) || in.minEdge[p] < 0)) {
            std::ostringstream s;
            s << "min_edge " << in.minEdge[p] << " is negative or not finite";
            fail(in, p, s.str());
        }
        for (int c = 0; c < 3; ++c) {
            float r = in.reflectance[p * 3 + c], e = in.emission[p * 3 + c];
            if (!std::isfinite(r) || r < 0 || r >= 1) {
                std::ostringstream s;
                s << "diffuse albedo " << r << " is outside [0, 1): a surface cannot reflect more light "
                  << "than it receives (use a base colour below 1)";
                fail(in, p, s.str());
            }
            if (!std::isfinite(e) || e < 0) {
                std::ostringstream s;
                s << "emission " << e << " is negative or not finite";
                fail(in, p, s.str());
            }
        }
    }
    scene.offset = raw.center();
    double rawDiagonal = length(raw.diagonal());
    // Faces below this area are numerically zero at the scene's scale (and at float32 input precision).
    double minArea = std::pow(1e-7 * rawDiagonal, 2);

    // Connected surfaces: union-find over the input vertices of every face, with vertices at
    // bit-identical positions taken as one (an edge-split or imported mesh repeats its vertices).
    std::vector<int32_t> parent(in.numVertices);
    {
        std::unordered_map<std::string, int32_t> first;
        first.reserve(in.numVertices);
        for (size_t v = 0; v < in.numVertices; ++v) {
            float c[3] = {in.vertices[v * 3] + 0.0f, in.vertices[v * 3 + 1] + 0.0f, in.vertices[v * 3 + 2] + 0.0f};
            auto [it, fresh] = first.emplace(std::string(reinterpret_cast<const char*>(c), sizeof c), int32_t(v));
            parent[v] = fresh ? int32_t(v) : it->second;
        }
    }
    auto findRoot = [&](int32_t v) {
        while (parent[size_t(v)] != v) {
            parent[size_t(v)] = parent[size_t(parent[size_t(v)])];
            v = parent[size_t(v)];
        }
        return v;
    };
    for (size_t p = 0; p < in.numPolygons; ++p) {
        const int32_t* idx = in.polygons + p * 4;
        int nv = idx[3] < 0 ? 3 : 4;
        for (int k = 1; k < nv; ++k) {
            int32_t a = findRoot(idx[0]), b = findRoot(idx[k]);
            if (a != b) parent[size_t(std::max(a, b))] = std::min(a, b);
        }
    }

    std::map<int, size_t> degenerateByObject;
    auto add = [&](const Polygon& geom, size_t p, bool back) {
        ScenePolygon sp;
        sp.geom = geom;
        if (back) std::reverse(sp.geom.v.begin(), sp.geom.v.begin() + sp.geom.n);
        sp.normal = sp.geom.normal();
        sp.area = sp.geom.area();
        uint8_t f = in.flags[p];
        sp.rho = {in.reflectance[p * 3], in.reflectance[p * 3 + 1], in.reflectance[p * 3 + 2]};
        sp.emission = {in.emission[p * 3], in.emission[p * 3 + 1], in.emission[p * 3 + 2]};
        sp.receives = !(f & kLightOnly);
        if (f & kLightOnly) sp.rho = {};
        sp.occludes = !(f & kLightOnly) && !back;
        sp.blocksLamps = !(f & kNoLampShadow);
        sp.castsShadow = !(f & kCastsNoShadow);
        sp.diffuseVisible = !(f & kNoDiffuse);
        sp.object = in.objectIndex[p];
        sp.input = int(p);
        sp.minEdge = in.minEdge ? in.minEdge[p] : 0;
        sp.surface = findRoot(in.polygons[p * 4]);
        scene.maxEmission = std::max(scene.maxEmission, maxComponent(sp.emission));
        scene.polygons.push_back(sp);
    };

    for (size_t p = 0; p < in.numPolygons; ++p) {
        const int32_t* idx = in.polygons + p * 4;
        int nv = idx[3] < 0 ? 3 : 4;
        Polygon g;
        for (int k = 0; k < nv; ++k) g.push(vertex(in, idx[k]) - scene.offset);
        if (g.area() <= minArea) {
            ++degenerateByObject[in.objectIndex[p]];
            ++scene.degenerateSkipped;
            continue;
        }
        Polygon parts[2];
        int count = 1;
        parts[0] = g;
        if (nv == 4 && !planarConvexQuad(g)) {
            splitQuad(g, parts[0], parts[1]);
            count = 2;
        }
        for (int k = 0; k < count; ++k) {
            if (parts[k].area() <= minArea) continue;
            add(parts[k], p, false);
            if (in.flags[p] & kEmitBack && !(in.flags[p] & kLightOnly)) add(parts[k], p, true);
        }
    }
    for (auto& [obj, count] : degenerateByObject) {
        std::string name = obj >= 0 && size_t(obj) < in.objectNames.size() ? in.objectNames[obj]
                                                                           : "#" + std::to_string(obj);
        scene.warnings.push_back("object '" + name + "': skipped " + std::to_string(count) +
                                 " zero-area face(s)");
    }
    bool anyReceiver = false;
    for (auto& sp : scene.polygons) {
        for (int k = 0; k < sp.geom.n; ++k) scene.bounds.extend(sp.geom.v[k]);
        anyReceiver |= sp.receives;
    }
    if (!anyReceiver)
        throw InputError("nothing to bake: the scene has no mesh faces with area" +
                         (scene.degenerateSkipped
                              ? " (" + std::to_string(scene.degenerateSkipped) + " zero-area face(s) skipped)"
                              : std::string()));
    for (const Light& l : in.lights) {
        auto name = [&] {
            return l.object >= 0 && size_t(l.object) < in.objectNames.size() ? "'" + in.objectNames[size_t(l.object)] + "'"
                                                                            : "#" + std::to_string(l.object);
        };
        auto bad = [&](const std::string& what) { throw InputError("light " + name() + ": " + what); };
        if (!isFinite(l.position) || !isFinite(l.direction) || !isFinite(l.value))
            bad("position, direction or value is NaN or infinite");
        if (l.value.x < 0 || l.value.y < 0 || l.value.z < 0) bad("negative power or colour");
        if (!(l.radius >= 0) || !std::isfinite(l.radius)) bad("radius must be >= 0");
        if (!(l.angle >= 0 && l.angle <= M_PI)) bad("sun angle must be in [0, 180] degrees");
        if (!(l.spotSize > 0 && l.spotSize <= M_PI) && l.type == LightType::Spot) bad("spot size must be in (0, 180] degrees");
        if (!(l.spotBlend >= 0 && l.spotBlend <= 1)) bad("spot blend must be in [0, 1]");
        if ((l.type == LightType::Spot || l.type == LightType::Sun) && !(length(l.direction) > 0))
            bad("zero direction");
        if (!l.env.empty()) {
            if (l.type != LightType::World) bad("only the world takes an environment image");
            if (l.envWidth <= 0 || l.envHeight <= 0 || l.env.size() != size_t(l.envWidth) * size_t(l.envHeight) * 3)
                bad("environment image size does not match its pixels");
            for (float x : l.env)
                if (!std::isfinite(x) || x < 0) bad("environment image has negative or non-finite pixels");
        }
        if (!(maxComponent(l.value) > 0)) continue;
        Light c = l;
        c.position = l.position - scene.offset;
        if (length(c.direction) > 0) c.direction = normalize(c.direction);
        scene.lights.push_back(c);
    }
    if (!(scene.maxEmission > 0) && scene.lights.empty())
        throw InputError("nothing emits light: add a light, an emissive material or a world colour");
    scene.diagonal = length(scene.bounds.diagonal());
    return scene;
}

}  // namespace penumbra
