#include "penumbra.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <type_traits>

#include "bake/lights.h"
#include "refine/refiner.h"
#include "solve/error_estimate.h"
#include "solve/solver.h"
#include "util/counters.h"
#include "util/error.h"
#include "util/parallel.h"
#include "visibility/ray_caster.h"

namespace penumbra {
namespace {

PENUMBRA_COUNTER(kPolygons, "polygons");
PENUMBRA_COUNTER(kElements, "elements");
PENUMBRA_COUNTER(kLeaves, "leaves");
PENUMBRA_COUNTER(kLinks, "links");
PENUMBRA_COUNTER(kClusters, "clusters");                   // cluster nodes
PENUMBRA_COUNTER(kClusterLinks, "cluster_links");          // links with a cluster at either end
PENUMBRA_COUNTER(kEmitterLinks, "emitter_links");          // element links whose source face emits
PENUMBRA_COUNTER(kConvolutionLinks, "convolution_links");
PENUMBRA_COUNTER(kConvolutionTexels, "convolution_texels");  // of all their textures
PENUMBRA_COUNTER(kGatherEmitters, "gather_emitters");  // emitting faces the final gather evaluates at every bake point
PENUMBRA_COUNTER(kIterations, "iterations");           // of the solver, over all refinement passes
PENUMBRA_COUNTER(kRefinePasses, "refine_passes");
PENUMBRA_COUNTER(kLights, "lights");          // point, spot and sun lamps and the world, when they give light
PENUMBRA_COUNTER(kSunTextures, "sun_textures");  // face x (sun or lamp with a size) shadows from a texture (sun_textures.h)
PENUMBRA_COUNTER(kSunRefused, "sun_refused");    // faces with blockers whose texture was refused (rays instead)
PENUMBRA_COUNTER(kLightRays, "light_rays");   // shadow rays to them for the solve's elements (not the bake's)

class Stopwatch {
public:
    double lap() {
        auto now = std::chrono::steady_clock::now();
        double s = std::chrono::duration<double>(now - last_).count();
        last_ = now;
        return s;
    }

private:
    std::chrono::steady_clock::time_point last_ = std::chrono::steady_clock::now();
};

// Every range comes from the table in solve/settings.h; the Python parser refuses wrong types before.
void validateSettings(const Settings& s) {
    forEachSetting(s, [](const SettingInfo& info, const auto& value) {
        using T = std::decay_t<decltype(value)>;
        if constexpr (!std::is_same_v<T, bool>) {
            if (!info.contains(double(value)))
                throw InputError(std::string("setting ") + info.key + " must be " +
                                 info.describe(std::is_integral_v<T>));
        }
    });
}

// A pair is linked at most once (each is reached from one parent pair), so the order is the same on any
// number of threads (parallelSort).
void sortLinks(std::vector<Link>& links, int threads) {
    parallelSort(links.begin(), links.end(), threads, [](const Link& a, const Link& b) {
        return a.receiver != b.receiver ? a.receiver < b.receiver : a.source < b.source;
    });
}

// After each refinement pass, on all threads: the 100k office's 4M links took 0.61 s over its three passes to
// renumber and sort on one thread while the other core waited, 0.47 s on two.
void remapLinks(std::vector<Link>& links, const std::vector<int>& remap, int threads) {
    parallelFor(links.size(), threads, 1 << 16, [&](size_t b, size_t e, int) {
        for (size_t i = b; i < e; ++i) {
            Link& l = links[i];
            if (!isClusterNode(l.receiver)) l.receiver = remap[size_t(l.receiver)];
            if (!isClusterNode(l.source)) l.source = remap[size_t(l.source)];
        }
    });
    sortLinks(links, threads);
}

}  // namespace

std::unique_ptr<Solution> solve(const SceneInput& in, const Settings& settings, Progress* progress) {
    validateSettings(settings);
    auto sol = std::unique_ptr<Solution>(new Solution());
    Report& rep = sol->report_;
    Counters counters;  // this solve's; copied into rep.counts at the end
    sol->threads_ = resolveThreads(settings.threads);
    sol->texelSamples_ = settings.texelSamples;
    sol->maxTexels_ = settings.maxTexels;
    Stopwatch clock;

    sol->scene_ = std::make_unique<Scene>(buildScene(in));
    const Scene& scene = *sol->scene_;
    counters.add(kPolygons, scene.polygons.size());
    rep.warnings = scene.warnings;
    sol->hierarchy_ = std::make_unique<Hierarchy>(scene, settings.maxElements, settings.clustering,
                                                    settings.planarClusters);
    Hierarchy& h = *sol->hierarchy_;
    rep.seconds["scene"] = clock.lap();
    checkProgress(progress, "visibility", 0.0);

    sol->rays_ = std::make_shared<RayCaster>(scene);
    const RayCaster& rays = *sol->rays_;
    if (!h.clusters().empty()) h.setBuried(rays.buriedFaces(scene, 1e-5 * scene.diagonal));
    rep.seconds["visibility_setup"] = clock.lap();

    // Lamps and the world light the faces before anything is linked: the faces' start radiosity is what
    // they reflect of it, so the refiner sees them as the sources they are, and its threshold is
    // relative to that light when no face emits (Refiner's scale).
    auto lightSet = std::make_shared<LightSet>(scene, &rays, settings.lightRays, settings.seed);
    LightStats lightStats;
    if (settings.convolution && !lightSet->empty()) {
        auto sun = std::make_shared<SunTextures>(scene, settings, sol->threads_);
        counters.add(kSunTextures, sun->made());
        counters.add(kSunRefused, sun->refused());
        if (sun->made() > 0) lightSet->setSunTextures(std::move(sun));
        rep.seconds["sun_textures"] = clock.lap();
    }
    if (!lightSet->empty()) {
        double flux = 0, area = 0;
        for (size_t i = 0; i < h.numRoots(); ++i) {
            Element& e = h[i];
            const ScenePolygon& p = scene.polygons[size_t(e.polygon)];
            if (!p.receives) continue;
            Rgb E = lightSet->elementIrradiance(e, p.normal, &lightStats);
            e.B = p.emission + mul(p.rho, E);
            if (maxComponent(p.rho) > 0) {
                flux += e.area * maxComponent(E);
                area += e.area;
            }
        }
        // A lamp has no exitance to scale the threshold by; it is taken as that of a panel covering
        // 1/50 of the receiving area and giving it the same light (the Cornell box's lamp covers 1/54):
        // rooms lit by lamps then refine like rooms lit by panels. Relative to the brightest irradiance
        // instead, a point lamp in a 2 m box refined every face to min_size (490k links, 40 s).
        sol->scene_->lightScale = area > 0 ? 50.0 * flux / area : 0.0;
        counters.add(kLights, scene.lights.size());
    }
    if (!lightSet->empty()) rep.seconds["lights"] = clock.lap();

    Refiner refiner(h, rays, settings, counters);
    rep.minEdge = refiner.minEdge();
    Solver solver(h, settings);
    solver.setClusterFaceVisibility(&refiner.faceVisibility());
    solver.setSourceFaceVisibility(&refiner.sourceFaceVisibility());
    std::vector<Rgb> lightE;  // per element, renewed with the leaves
    auto attachLights = [&] {
        if (lightSet->empty()) return;
        lightE = lightSet->leafIrradiance(h, sol->threads_, &lightStats);
        solver.setLightIrradiance(&lightE);
    };
    std::vector<Link>& links = sol->links_;
    std::vector<ConvolutionLink>& conv = sol->convLinks_;
    CompleteTextures textures;
    // Leaves change with every refinement pass, and with them the complete textures.
    auto attachTextures = [&] {
        conv = refiner.convolutionLinks();
        textures = CompleteTextures(h, conv, sol->threads_);
        solver.setConvolution(&conv, &textures);
    };
    h.updateClusterFlux();
    links = refiner.linkAll(progress);
    remapLinks(links, h.canonicalize(sol->threads_), sol->threads_);
    attachTextures();
    attachLights();
    rep.seconds["refine"] = clock.lap();
    // The solves before the last refinement pass only feed the re-judging of the links: they stop at an
    // estimated remaining error of kPassTolerance (or the tolerance, if that is looser), and the last solve at
    // the tolerance itself. At 10 times the tolerance (stop 29; 1e-3 by default) the 10k office at epsilon
    // 0.002 took 17 sweeps where it took 22. At 0.1 (stop 39): the 20k office 18 -> 12 sweeps and 2.7 % fewer
    // links (a radiosity still short of its last bounces asks for fewer reflector links), 100k office
    // 142 -> 115 CPU s of the bake call with the change before it; against Cycles the five benchmark rooms at
    // epsilon 0.002 and 0.0002 moved by -0.03 to 0.00 points per face, the 20k and 100k offices 4.00 ->
    // 3.98 % and 6.85 -> 6.84 % (docs/scaling.md).
    constexpr double kPassTolerance = 0.1;
    bool loose = settings.refinePasses > 1;
    if (loose) solver.setTolerance(std::max(settings.tolerance, kPassTolerance));
    SolveResult res = solver.solve(links, progress);
    rep.seconds["solve"] = clock.lap();
    int passes = 1, totalIterations = res.iterations;
    for (int pass = 1; pass < settings.refinePasses; ++pass) {
        bool changed = false;
        h.updateRadiosityDeviation();
        refiner.setSolvedTextures(conv, textures);
        // The last pass also weighs the kept links again by their sources' parts' light of now, as the links it
        // makes are weighed (Refiner::rerefine): what the final solve reads.
        refiner.rerefine(links, progress, changed, pass == settings.refinePasses - 1);
        remapLinks(links, h.canonicalize(sol->threads_), sol->threads_);
        rep.seconds["refine"] += clock.lap();
        if (!changed) break;  // no element was split: the complete textures still fit the leaves
        if (loose && pass == settings.refinePasses - 1) {
            solver.setTolerance(settings.tolerance);
            loose = false;
        }
        attachTextures();
        attachLights();
        rep.seconds["refine"] += clock.lap();
        res = solver.solve(links, progress);
        totalIterations += res.iterations;
        passes = pass + 1;
        rep.seconds["solve"] += clock.lap();
    }
    if (loose) {  // the passes ended early, after a loose solve: finish it at the tolerance
        solver.setTolerance(settings.tolerance);
        res = solver.solve(links, progress);
        totalIterations += res.iterations;
        rep.seconds["solve"] += clock.lap();
    }
    counters.add(kRefinePasses, size_t(passes));
    if (!lightSet->empty()) counters.add(kLightRays, lightStats.rays);
    counters.add(kIterations, size_t(totalIterations));
    rep.residual = res.residual;
    rep.converged = res.converged;
    if (!res.converged)
        rep.warnings.push_back("solver stopped after max_iterations with estimated error " +
                               std::to_string(res.residual));
    if (res.overGathering > 0)
        rep.warnings.push_back(std::to_string(res.overGathering) +
                               " elements gathered more light than their hemisphere holds (form factors summing to " +
                               std::to_string(res.maxGathered) +
                               "; faces meeting at a hair's angle or overlapping?): their light was capped");

    if (settings.finalGather) {
        // Emitting faces whose light a convolution link's texture already draws on a receiver.
        std::vector<std::vector<int>> excluded(scene.polygons.size());
        for (const ConvolutionLink& l : conv)
            for (int r : l.receiverPolygons)
                excluded[size_t(r)].insert(excluded[size_t(r)].end(), l.sourcePolygons.begin(), l.sourcePolygons.end());
        for (auto& v : excluded) {
            std::sort(v.begin(), v.end());
            v.erase(std::unique(v.begin(), v.end()), v.end());
        }
        // With gather_rays = 0 the gather takes each leaf's visibility from its links, whose rays meet
        // every polygon; an object hidden from shadow rays (kNoLampShadow) must let the emitters' light
        // through, so then the gather casts its own shadow rays (light_rays of them, as the lamps do). So
        // must a light that casts no shadow (kCastsNoShadow): one visibility per leaf cannot hold it and
        // a shadowed emitter at once.
        int gatherRays = settings.gatherRays;
        if (gatherRays == 0)
            for (const ScenePolygon& p : scene.polygons)
                if (!p.blocksLamps || !p.castsShadow) {
                    gatherRays = settings.lightRays;
                    break;
                }
        auto direct = std::make_shared<DirectLight>(scene, rays, gatherRays, std::move(excluded), settings.seed);
        std::vector<Rgb> shadowed, unoccluded;
        solver.directIrradiance(links, shadowed, unoccluded);
        std::vector<Rgb> reflected = conv.empty() ? std::vector<Rgb>{} : textures.reflected(h, conv);
        sol->field_ = RadianceField(h, reflected, conv.empty() ? ConvolutionField{} : ConvolutionField(h, conv),
                                    shadowed, unoccluded, direct,
                                    lightSet->empty() ? nullptr : lightSet, lightE);
        counters.add(kGatherEmitters, direct->emitters());
    } else {
        sol->field_ = conv.empty() ? RadianceField(h)
                                   : RadianceField(h, textures.reflected(h, conv), ConvolutionField(h, conv));
    }
    ErrorEstimate est = estimateError(h, links, settings, res.residual);
    rep.errorEstimate = est.overall;
    rep.objectErrorEstimate = est.perObject;
    rep.seconds["reconstruct"] = clock.lap();
    counters.add(kElements, h.size());
    counters.add(kLeaves, h.countLeaves());
    counters.add(kLinks, links.size());
    counters.add(kClusters, h.clusters().size());
    counters.add(kClusterLinks, size_t(std::count_if(links.begin(), links.end(), [](const Link& l) {
        return isClusterNode(l.receiver) || isClusterNode(l.source);
    })));
    counters.add(kEmitterLinks, size_t(std::count_if(links.begin(), links.end(), [&](const Link& l) {
        return !isClusterNode(l.receiver) && !isClusterNode(l.source) &&
               maxComponent(scene.polygons[size_t(h[l.source].polygon)].emission) > 0;
    })));
    counters.add(kConvolutionLinks, conv.size());
    for (const ConvolutionLink& l : conv) {
        for (const auto& t : l.textures)
            if (t) counters.add(kConvolutionTexels, size_t(t->n) * size_t(t->n));  // null: a band in full light
        rep.convolutionMaxError = std::max(rep.convolutionMaxError, l.error);
    }
    if (const ConvolutionSites* cs = refiner.convolutionSites())
        rep.seconds["convolution_textures"] = cs->textureSeconds();  // within "refine"
    rep.counts = counters.values();
    checkProgress(progress, "solve", 1.0);
    return sol;
}

std::vector<float> Solution::radiance(const float* points, const float* normals, size_t n, bool irradiance) const {
    std::vector<float> out(n * 3);
    const Vec3 off = scene_->offset;
    parallelFor(n, threads_, 1024, [&](size_t b, size_t e, int) {
        for (size_t i = b; i < e; ++i) {
            Vec3 p{points[i * 3], points[i * 3 + 1], points[i * 3 + 2]};
            Vec3 nn{normals[i * 3], normals[i * 3 + 1], normals[i * 3 + 2]};
            Rgb r = field_.radiance(p - off, normalize(nn), irradiance);
            out[i * 3] = float(r.x);
            out[i * 3 + 1] = float(r.y);
            out[i * 3 + 2] = float(r.z);
        }
    });
    return out;
}

void Solution::checkTexelBudget(const LightmapInput& in) const {
    const size_t maxTexels = maxTexels_;
    if (in.width > 0 && in.height > 0 && size_t(in.width) * size_t(in.height) > maxTexels)
        throw BudgetExceeded("memory guard: a " + std::to_string(in.width) + " x " + std::to_string(in.height) +
                             " lightmap is more than max_texels = " + std::to_string(maxTexels) +
                             " texels (about 60 bytes each while baking); lower the resolution or raise "
                             "max_texels");
}

std::vector<float> Solution::bakeLightmap(const LightmapInput& in) const {
    checkTexelBudget(in);
    LightmapInput with = in;
    with.footprint = texelSamples_;
    return penumbra::bakeLightmap(field_, with, scene_->offset, threads_);
}

void Solution::bakeLightmaps(const LightmapInput* ins, size_t count, float* out) const {
    std::vector<LightmapInput> with(ins, ins + count);
    for (LightmapInput& in : with) {
        checkTexelBudget(in);
        in.footprint = texelSamples_;
    }
    penumbra::bakeLightmaps(field_, with.data(), count, scene_->offset, threads_, out);
}

}  // namespace penumbra
