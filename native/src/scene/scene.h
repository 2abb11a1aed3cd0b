// The scene as the solver sees it: planar convex triangles and quads with a reflectance and an
// emission each, validated and recentred. Everything upstream (Blender, tests, fuzzers) speaks to the
// solver only through SceneInput.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "geometry/polygon.h"

namespace penumbra {

enum PolygonFlags : uint8_t {
    kEmitBack = 1,   // emits B_e from the back side too (Cycles mesh emitters are two-sided)
    kLightOnly = 2,  // a lamp: emits, but neither receives, reflects nor blocks
    // Blender's Ray Visibility > Shadow off: shadow rays pass through it: the lamps' (point, spot, sun)
    // and the final gather's to area lights and emitting faces. The world's rays and the hierarchy's
    // links (which carry the reflected light too, and the direct light only into the bounce) still
    // see it as a blocker: Cycles' diffuse rays meet it.
    kNoLampShadow = 4,
    // An AREA light whose Cast Shadow is off: its light passes every object, at each texel (the final
    // gather casts no rays to it) and along the element links it sends on (the refiner takes them as
    // unoccluded). Cluster links from a cluster holding it still see blockers.
    kCastsNoShadow = 8,
    // Blender's Ray Visibility > Diffuse off: diffuse bounce rays pass through it. It sends none of the light
    // it reflects (only its emission, if any), and the links between other faces that carry reflected light
    // (from sources that do not emit) see through it; it still receives light and blocks the lamps', the
    // emitters' and the world's.
    kNoDiffuse = 16,
};

// A Blender lamp that is not a polygon, in Cycles' units (blender-facts.md section 1). Point and spot:
// `value` is the power P (W, times the colour), radiant intensity P/(4 pi). With a radius r Cycles draws
// either a disk of radius r facing the shaded point (every 3.x lamp, and 4.0+ with Soft Falloff, the
// default), so E = P cos / (4 pi (d^2 + r^2)), or (`sphere`: 4.0+ without Soft Falloff) a sphere of
// radius r and uniform radiance P / (4 pi^2 r^2), so E = P cos / (4 pi d^2) while the sphere is wholly
// above the receiver's horizon. Sun: `value`
// is the strength (W/m^2 at normal incidence for angle 0). World: `value` is the background's
// radiance (colour x strength), the same from every direction.
enum class LightType : uint8_t { Point = 0, Spot = 1, Sun = 2, World = 3 };

struct Light {
    LightType type = LightType::Point;
    Vec3 position;          // point, spot
    Vec3 direction{0, 0, -1};  // spot axis and sun: the way the light travels (the lamp's local -Z)
    Rgb value;
    double radius = 0;      // point, spot: the disk or sphere Cycles samples (shadow_soft_size)
    bool sphere = false;    // point, spot: a sphere of uniform radiance rather than a disk facing the point
    double spotSize = 0;    // spot: full cone angle, radians
    double spotBlend = 0;   // spot: [0, 1]
    bool spotCosine = true; // spot: Cycles 3.x also multiplies by the cosine from the axis (4.0 dropped it)
    double angle = 0;       // sun: angular diameter, radians
    bool castShadow = true;
    int object = -1;        // index into objectNames, for messages
    // World only: an equirectangular environment (Cycles' Environment Texture, default mapping), linear
    // RGB rows from the bottom (v = 0, straight down) up; `value` multiplies it (the Background strength).
    // Empty: the uniform `value`.
    int envWidth = 0, envHeight = 0;
    std::vector<float> env;
};

// Borrowed views of the caller's arrays (row-major). Nothing is copied until buildScene.
struct SceneInput {
    const float* vertices = nullptr;      // numVertices x 3
    size_t numVertices = 0;
    const int32_t* polygons = nullptr;    // numPolygons x 4, -1 in column 3 for triangles
    size_t numPolygons = 0;
    const float* reflectance = nullptr;   // numPolygons x 3
    const float* emission = nullptr;      // numPolygons x 3, exitance B_e in W/m^2
    const uint8_t* flags = nullptr;       // numPolygons, PolygonFlags
    const int32_t* objectIndex = nullptr; // numPolygons, index into objectNames
    std::vector<std::string> objectNames;
    // numPolygons or null: per face, the finest element edge in metres (0: min_size x the scene's
    // diagonal). The add-on passes a lightmap's texel size, so a large hall is meshed as finely as its
    // lightmaps can show and a small room no finer than they can.
    const float* minEdge = nullptr;
    std::vector<Light> lights;  // world coordinates; copied
};

struct ScenePolygon {
    Polygon geom;   // recentred world coordinates, counter-clockwise around `normal`
    Vec3 normal;
    double area = 0;
    Rgb rho, emission;
    bool receives = true;   // takes part as a receiver and reflector
    bool occludes = true;   // put in the ray-tracing scene (a back-side copy shares its twin's triangles)
    bool blocksLamps = true;  // and in the one the lamps' shadow rays use (kNoLampShadow clears it)
    bool castsShadow = true;  // its light is blocked by anything (kCastsNoShadow clears it)
    bool diffuseVisible = true;  // diffuse bounce rays meet it (kNoDiffuse clears it)
    int object = -1;
    int input = -1;         // index of the input polygon it came from
    // Faces joined through shared input vertices, transitively: one connected surface. The display
    // blends elements of one surface only, so two rooms whose walls share a plane stay apart.
    int surface = -1;
    // The finest element edge the refiner may cut this face into, metres; 0: the scene's min_size rule.
    double minEdge = 0;
};

// A two-sided face's back copy is added right after its front and shares its triangles (buildScene): the
// polygon whose triangles a ray meets for polygon i, and whether polygon i has such a copy.
inline bool isBackCopy(const std::vector<ScenePolygon>& polys, size_t i) {
    return i > 0 && !polys[i].occludes && polys[i - 1].input == polys[i].input;
}
inline size_t occluderOf(const std::vector<ScenePolygon>& polys, size_t i) { return isBackCopy(polys, i) ? i - 1 : i; }
inline bool hasBackCopy(const std::vector<ScenePolygon>& polys, size_t i) {
    return i + 1 < polys.size() && isBackCopy(polys, i + 1);
}

inline Bounds polygonBox(const ScenePolygon& p) {
    Bounds b;
    for (int k = 0; k < p.geom.n; ++k) b.extend(p.geom.v[k]);
    return b;
}

struct Scene {
    std::vector<ScenePolygon> polygons;
    std::vector<std::string> objectNames;
    Vec3 offset;            // subtracted from every input coordinate: Embree works in float32
    Bounds bounds;          // of the recentred scene
    double diagonal = 0;
    double maxEmission = 0; // brightest emitted radiosity over channels, the scale of all thresholds
    std::vector<Light> lights;  // recentred; only those that give light
    // The lights' scale for the refiner's threshold, as maxEmission is the emitters': 50 times the mean
    // irradiance they give the reflecting faces (max channel; penumbra.cpp says why). Set by solve() once
    // it is known; 0 without lights.
    double lightScale = 0;
    size_t degenerateSkipped = 0;
    std::vector<std::string> warnings;
};

// Validates and converts. Throws InputError naming the object for NaN/Inf coordinates, indices out
// of range, albedo outside [0, 1), negative or non-finite emission or light values, an empty scene
// or one where nothing emits (no emitting face and no light). Zero-area faces are skipped (and counted); non-planar or non-convex quads are split
// into two triangles.
Scene buildScene(const SceneInput& in);

}  // namespace penumbra
