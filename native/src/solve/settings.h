// The user's knobs. Thresholds are relative (to the brightest emitter, to the scene's size) so that
// a scene baked in millimetres or kilometres refines the same way.
//
// PENUMBRA_SETTINGS is the solver's one list of settings. Each X(type, member, key, default, lo, min,
// max, hi) line gives the Settings member, its key in the Python settings dict, its default and the
// range the solver accepts, written as an interval: lo is '[' or '(', hi is ']' or ')'; an open bound
// refuses the bound itself, so "(0, kNoBound)" is any finite number above 0 and "[1, kNoBound]" also
// takes infinity. The struct's members, validateSettings (penumbra.cpp), the Python binding's parser
// and its exported table `_native.SETTINGS` all come from this list, so they cannot disagree.
//
// The add-on's table, addon/penumbra/settings_table.py, holds the same names, defaults and ranges plus
// what only the UI needs (label, help, panel group); the panel's properties, the CLI's flags and
// penumbra.bake()'s keywords are built from it. native/python/test_settings_table.py fails when the
// two tables differ. Adding a setting is one X(...) line here and one Setting(...) entry there.
#pragma once
#include <cstddef>
#include <limits>
#include <string>

namespace penumbra {

inline constexpr double kNoBound = std::numeric_limits<double>::infinity();

// clang-format off
#define PENUMBRA_SETTINGS(X)                                                                               \
    /* max radiosity error of a link, relative to the brightest emitter */                                  \
    X(double, epsilon, "epsilon", 0.0002, '(', 0, kNoBound, ')')                                           \
    /* smallest element edge, relative to the smaller of the scene's bounding-box diagonal and 35 median     \
       pieces (faces joined by shared corners; refiner.cpp): a hall grows, its furniture does not */        \
    X(double, minSize, "min_size", 0.01, '(', 0, 1, ')')                                                   \
    /* rays per link estimate (rounded to a square number of strata) */                                     \
    X(int, visibilityRays, "visibility_rays", 16, '[', 1, 256, ']')                                        \
    /* sweeps per refinement pass; albedo 0.99 needs ~1000 for 1e-4 */                                      \
    X(int, maxIterations, "max_iterations", 5000, '[', 1, std::numeric_limits<int>::max(), ']')            \
    /* stop when the estimated remaining relative error falls below this */                                 \
    X(double, tolerance, "tolerance", 1e-4, '(', 0, 1, ')')                                                \
    /* refine -> solve rounds (later passes refine with indirect light) */                                  \
    X(int, refinePasses, "refine_passes", 3, '[', 1, 20, ']')                                              \
    /* 0: all cores */                                                                                      \
    X(int, threads, "threads", 0, '[', 0, 1024, ']')                                                       \
    /* refine from one root <-> root cluster link instead of all face pairs */                              \
    X(bool, clustering, "clustering", true, '[', 0, 1, ']')                                                \
    /* Convolution links (Soler & Sillion 1998, Fig. 4): a large planar receiver lit by a planar emitter     \
       through blockers gets one soft shadow texture instead of a subdivided mesh of standard links. */     \
    X(bool, convolution, "convolution", true, '[', 0, 1, ']')                                              \
    /* smallest receiver for a convolution link: box diagonal / scene diagonal */                           \
    X(double, aMin, "a_min", 0.15, '[', 0, kNoBound, ')')                                                  \
    /* largest blocker error E_rr of a convolution link, in texels of half the narrowest penumbra */        \
    X(double, eMax, "e_max", 1.0, '(', 0, kNoBound, ')')                                                   \
    /* largest predicted FFT time of one convolution link, seconds */                                       \
    X(double, tMax, "t_max", 0.05, '(', 0, kNoBound, ')')                                                  \
    /* largest soft shadow texture, texels per side */                                                      \
    X(int, maxTexture, "max_texture", 512, '[', 16, 4096, ']')                                             \
    /* Contact sub-blockers (issue 12): a blocker resting on its receiver is cut into clipped depth slabs     \
       so the pair can take a texture. Off by default: on the Cornell box its floor's one texture moved the  \
       per-face error against Cycles from 1.17 % to 1.52 % (box-on-floor scenes: 2.4 % -> 0.7 % RMS). */   \
    X(bool, contactSlabs, "contact_slabs", false, '[', 0, 1, ']')                                          \
    /* Planar clusters (issue 12): the cluster tree keeps faces lying in one plane together, so a floor or   \
       wall modelled in one mesh with others, or a triangulated table top, is one planar cluster, one        \
       convolution receiver. Off by default: flat clusters make fewer cluster links (a tessellated furnace   \
       box: 884 -> 0). */                                                                                    \
    X(bool, planarClusters, "planar_clusters", false, '[', 0, 1, ']')                                      \
    /* Wall links (issue 12): a receiver steep to its source (a wall under a ceiling lamp) is cut into      \
       bands of depth along the source's normal, each with its own textures, the blockers clipped above the  \
       band (a shelf before a wall: 0.64 % worst against the exact light). Off by default: it moves results  \
       wherever it links (classroom walls and chair backs) and was not scored against Cycles. */             \
    X(bool, wallLinks, "wall_links", false, '[', 0, 1, ']')                                                \
    /* Cluster receivers (issue 12): a cluster whose faces do not share one plane (a vault, a terrain, the    \
       paper's desk clusters) may take one convolution link, each face lit through the textures at its own     \
       position and normal; a cluster whose own faces shade each other from the source is refused (an exact  \
       test, counted as self_shadow) and refined as before. On by default since stop 33: the six benchmark   \
       rooms bake identically, a curved floor under a lattice 4x faster at the default at better error. */   \
    X(bool, clusterReceivers, "cluster_receivers", true, '[', 0, 1, ']')                                   \
    /* Indirect sources (issue 12): a reflecting face (or a planar group of them) lit by the first pass is   \
       a convolution source too, its source image drawn from its own radiosity and the shadow textures it    \
       receives (the paper's source "rendered with all its radiosity textures", §4.1). Off by default: not   \
       scored against Cycles on furnished rooms. */                                                          \
    X(bool, indirectSources, "indirect_sources", false, '[', 0, 1, ']')                                    \
    /* A cluster source is linked whole only when its radius is at most far_field of its distance to       \
       the receiver; nearer, it is opened (its light is evaluated face by face there, node.cpp, but        \
       with one visible share). 0.3 since stop 30 (0.2 before): the 10k office at epsilon 0.002 takes      \
       1.31M links instead of 2.37M and 29 % less CPU, and against Cycles it is as good or better at       \
       equal run time (the 5k office 2.82 % per face in 2.9 CPU s at epsilon 0.001, against 2.74 % in      \
       3.7 s at 0.2 and 0.002; at the default epsilon 2.14 against 2.20 %). An open safe's inside stays     \
       2.3 % of the peak off the face-by-face solve (2.6 % at 0.2); from 0.35 it is 4.3 % and 6.0 % at     \
       0.5, where one share per face of a cluster receiver stands for a penumbra across the face.          \
       docs/scaling.md. */                                                                                 \
    X(double, farField, "far_field", 0.3, '(', 0, 1, ']')                                                  \
    /* Nearer than that, a cluster source whose whole transfer is within epsilon is linked all the same:    \
       into an element as one link whose light is summed face by face, each face with its own form factor   \
       and visible share (4 rays a face); into a cluster receiver of up to 64 faces as a far source is,      \
       each receiving face with its own share. Opened instead, it made a link per face (16 rays each). On by \
       default since stop 37: the 50k office at epsilon 0.002 takes 25 % less time and 46 % fewer links;    \
       against Cycles the five benchmark rooms moved by -0.15 to +0.07 points per face (docs/scaling.md). */  \
    X(bool, sourceShares, "source_shares", true, '[', 0, 1, ']')                                           \
    /* Contact floor (issue 14, item 2): min_size is a share of the scene's diagonal, so a large room is   \
       meshed coarsely everywhere, also where a small object stands on a large face (a monitor's 6 cm stand\
       on a desk, whose light just in front of the stand sets the stand's). With k > 0, a face that a face \
       of another object comes within twice its own size of may be cut down to k times that size (never    \
       below 1 mm). Off by default: on the 5k scaling office at the default epsilon 1 gives 3.20 % per face\
       against Cycles for twice the time, 2 gives 3.46 % for about a third more (3.97 % without), and at   \
       20k polygons it costs more than it buys (docs/scaling.md). */                                       \
    X(double, contactFloor, "contact_floor", 0.0, '[', 0, kNoBound, ')')                                   \
    /* Final gather: the emitters' light is evaluated exactly at every bake point (form factor times         \
       visibility) instead of read from the elements; the hierarchy carries the reflected remainder. */     \
    X(bool, finalGather, "final_gather", true, '[', 0, 1, ']')                                             \
    /* Visibility of the gathered light: 0 takes it from the hierarchy's links (their shadowed over         \
       unoccluded light, blended like the radiosity); N > 0 casts up to N rays per emitter group and        \
       point to fixed Sobol' points (exact in full light and umbra, but a detailed shadow such as a         \
       lattice shade needs hundreds: 4.8 % RMS with 64, 1.6 % with 256, against 0.9 % from the links). */  \
    X(int, gatherRays, "gather_rays", 0, '[', 0, 256, ']')                                                 \
    /* Point, spot and sun lamps and the world: sample points per light and bake point for the soft        \
       shadow of a lamp with a size (radius, sun angle) and the world's occlusion; up to 32 per element     \
       for the light the solve carries on. A hard-shadowed lamp (radius 0) always takes one ray. */         \
    X(int, lightRays, "light_rays", 256, '[', 1, 1024, ']')                                                 \
    /* Lightmap texels where the light bends within a texel (a shadow's edge, a contact) take the mean over  \
       their footprint as Blender 3.4's bake samples it (bake/lightmap.h), from this many points per side;    \
       1, the default: every texel its centre. It helps where the light is exact per point (lamps, the       \
       gather's own rays) and not where shadows come from the elements (the 100k office, docs/scaling.md). */ \
    X(int, texelSamples, "texel_samples", 1, '[', 1, 16, ']')                                              \
    /* Which sample pattern the rays use (links' visibility, faces' shares, lamps' and the gather's points): \
       0 is the default pattern; another seed gives a bake that differs from it by sampling noise alone. */ \
    X(int, seed, "seed", 0, '[', 0, std::numeric_limits<int>::max(), ']')                                 \
    /* Budgets: a scene that would exceed one stops with BudgetExceeded before the memory is taken,         \
       instead of being killed by the system (or, for face pairs, running for hours). */                    \
    /* quadtree elements, ~400 bytes each at the peak (canonicalize) */                                     \
    X(size_t, maxElements, "max_elements", 2000000, '[', 1, size_t(1) << 30, ']')                          \
    /* links, ~72 bytes each at the peak (per-thread lists, merge, sort). 60M since stop 38: the 100k office \
       at the default epsilon takes 34.0M links, 2.1 GB at its peak and 183 s, where 30M refused it. */      \
    X(size_t, maxLinks, "max_links", 60000000, '[', 1, kNoBound, ']')                                      \
    /* receiver x source face pairs linkAll visits without clustering */                                    \
    X(double, maxFacePairs, "max_face_pairs", 1e9, '[', 1, kNoBound, ']')                                  \
    /* one bake_lightmap call, ~60 bytes each */                                                            \
    X(size_t, maxTexels, "max_texels", size_t(8192) * 8192, '[', 1, kNoBound, ']')
// clang-format on

struct Settings {
#define PENUMBRA_SETTING_MEMBER(type, member, key, value, lo, min, max, hi) type member = value;
    PENUMBRA_SETTINGS(PENUMBRA_SETTING_MEMBER)
#undef PENUMBRA_SETTING_MEMBER
};

// One row of the table without its value: the key and the accepted interval.
struct SettingInfo {
    const char* key;
    char lo;     // '[' or '('
    double min;
    double max;  // kNoBound: no upper limit
    char hi;     // ']' or ')'

    bool contains(double x) const {  // false for NaN
        return (lo == '(' ? x > min : x >= min) && (hi == ')' ? x < max : x <= max);
    }
    // "in [1, 256]", "in (0, 1)", "a finite number > 0", "at least 1": what an error message says
    // the value must be. settings_table.describe() in the add-on writes the same words.
    std::string describe(bool integer) const;
};

// Calls f(info, member) for every setting of s, in the table's order; member is a reference to the
// field (const when s is), so one walk validates, parses or exports.
template <class S, class F>
void forEachSetting(S& s, F&& f) {
#define PENUMBRA_SETTING_VISIT(type, member, key, value, lo, min, max, hi) \
    f(SettingInfo{key, lo, double(min), double(max), hi}, s.member);
    PENUMBRA_SETTINGS(PENUMBRA_SETTING_VISIT)
#undef PENUMBRA_SETTING_VISIT
}

}  // namespace penumbra
