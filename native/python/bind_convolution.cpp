// Python entry of the convolution stage: soft_shadow_texture() computes one soft shadow texture on
// its own (source polygon, blocker triangles, receiver polygon), lookup() reads it at 3D points.
// The bench_* functions exist for examples/bench_convolution.py.
#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <chrono>
#include <cmath>
#include <string>

#include "bindings.h"
#include "convolution/cost_model.h"
#include "convolution/fft_convolver.h"
#include "convolution/raster.h"
#include "convolution/soft_shadow.h"
#include "convolution/sun_shadow.h"

namespace py = pybind11;

namespace penumbra::python {
namespace {

using F64 = py::array_t<double, py::array::c_style | py::array::forcecast>;
using F32 = py::array_t<float, py::array::c_style | py::array::forcecast>;

// Any numeric array-like of the given shape (-1 = any length), converted to float64; non-finite
// values are refused with the argument's name.
F64 asDoubles(const py::handle& obj, const char* name, std::vector<py::ssize_t> shape) {
    F64 a;
    try {
        a = F64::ensure(obj);
    } catch (...) {
    }
    if (!a) throw py::value_error(std::string(name) + " must be a numeric array");
    bool ok = a.ndim() == static_cast<py::ssize_t>(shape.size());
    for (size_t i = 0; ok && i < shape.size(); ++i) ok = shape[i] < 0 || a.shape(i) == shape[i];
    if (!ok) {
        std::string want = "(";
        for (size_t i = 0; i < shape.size(); ++i)
            want += (shape[i] < 0 ? std::string("any") : std::to_string(shape[i])) + (i + 1 < shape.size() ? ", " : ")");
        std::string got = "(";
        for (py::ssize_t i = 0; i < a.ndim(); ++i) got += std::to_string(a.shape(i)) + (i + 1 < a.ndim() ? ", " : "");
        throw py::value_error(std::string(name) + " must have shape " + want + ", got " + got + ")");
    }
    const double* d = a.data();
    for (py::ssize_t i = 0; i < a.size(); ++i)
        if (!std::isfinite(d[i])) throw py::value_error(std::string(name) + " contains a non-finite value");
    return a;
}

std::vector<Vec3> points(const F64& a) {
    std::vector<Vec3> out(a.shape(0));
    const double* d = a.data();
    for (size_t i = 0; i < out.size(); ++i) out[i] = {d[3 * i], d[3 * i + 1], d[3 * i + 2]};
    return out;
}

DirectionChoice parseDirection(const std::string& s) {
    if (s == "auto") return DirectionChoice::Auto;
    if (s == "source_to_receiver") return DirectionChoice::SourceToReceiver;
    if (s == "receiver_normal") return DirectionChoice::ReceiverNormal;
    if (s == "source_normal") return DirectionChoice::SourceNormal;
    throw py::value_error("direction must be auto, source_to_receiver, receiver_normal or source_normal");
}
const char* directionName(DirectionChoice d) {
    switch (d) {
        case DirectionChoice::Auto: return "auto";
        case DirectionChoice::SourceToReceiver: return "source_to_receiver";
        case DirectionChoice::ReceiverNormal: return "receiver_normal";
        case DirectionChoice::SourceNormal: return "source_normal";
    }
    return "?";
}

py::tuple vec(const Vec3& v) { return py::make_tuple(v.x, v.y, v.z); }

py::dict softShadowTexture(const py::object& source, const py::object& receiver, const py::object& blockers,
                           const py::object& resolution, const py::object& emissionImage, double eMax, int nMax,
                           const std::string& rasterizer, int supersample, const std::string& direction,
                           int minResolution, int maxResolution, double depthTolerance, bool contactSlabs) {
    SourceDesc src;
    src.polygon = points(asDoubles(source, "source", {-1, 3}));
    if (src.polygon.size() < 3) throw py::value_error("source must have at least 3 vertices");
    ReceiverDesc rec;
    rec.points = points(asDoubles(receiver, "receiver", {-1, 3}));
    if (rec.points.size() < 3) throw py::value_error("receiver must have at least 3 vertices");
    std::vector<BlockerTriangle> tris;
    {
        F64 b = asDoubles(blockers, "blockers", {-1, 3, 3});
        tris.resize(b.shape(0));
        const double* d = b.data();
        for (size_t t = 0; t < tris.size(); ++t)
            for (int k = 0; k < 3; ++k) tris[t][k] = {d[9 * t + 3 * k], d[9 * t + 3 * k + 1], d[9 * t + 3 * k + 2]};
    }
    if (!emissionImage.is_none()) {
        F64 e = asDoubles(emissionImage, "emission_image", {-1, -1});
        src.emission.height = static_cast<int>(e.shape(0));
        src.emission.width = static_cast<int>(e.shape(1));
        if (src.emission.width == 0 || src.emission.height == 0) throw py::value_error("emission_image is empty");
        src.emission.texels.assign(e.data(), e.data() + e.size());
    }
    ConvolutionSettings s;
    if (!resolution.is_none()) {
        s.resolution = resolution.cast<int>();
        if (s.resolution < 1) throw py::value_error("resolution must be a positive int or None");
    }
    s.e_max = eMax;
    s.n_max = nMax;
    s.rasterizer = parseRasterizerKind(rasterizer);
    s.supersample = supersample;
    s.direction = parseDirection(direction);
    s.minResolution = minResolution;
    s.maxResolution = maxResolution;
    s.depthTolerance = depthTolerance;
    s.contactSlabs = contactSlabs;

    ConvolutionPlan plan;
    SoftShadowTexture T;
    {
        py::gil_scoped_release nogil;
        auto t0 = std::chrono::steady_clock::now();
        plan = planSoftShadow(src, tris, rec, s);
        double planMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
        T = computeSoftShadow(plan, src, tris, s);
        T.times.restMs += planMs;
    }
    F32 vis({T.n, T.n});
    std::copy(T.visibility.begin(), T.visibility.end(), vis.mutable_data());
    F64 m({4, 4});
    std::copy(T.matrix.begin(), T.matrix.end(), m.mutable_data());
    py::dict times;
    times["raster_ms"] = T.times.rasterMs;
    times["fft_ms"] = T.times.fftMs;
    times["rest_ms"] = T.times.restMs;
    py::dict frame;
    frame["origin"] = vec(T.frame.O);
    frame["u"] = vec(T.frame.u);
    frame["v"] = vec(T.frame.v);
    frame["w"] = vec(T.frame.w);
    frame["direction"] = directionName(plan.direction);
    py::dict window;
    window["z_r"] = T.window.z_r;
    window["u_lo"] = T.window.u_lo;
    window["v_lo"] = T.window.v_lo;
    window["extent"] = T.window.extent;
    window["texel"] = plan.p;
    py::list slices;
    for (const SubBlocker& b : plan.slices) {
        py::dict d;
        d["triangles"] = b.triangles.size();
        d["pieces"] = b.pieces.size();
        d["depth"] = py::make_tuple(b.depth.lo, b.depth.hi);
        d["alpha"] = py::make_tuple(b.alphaLo, b.alphaStar, b.alphaHi);
        d["error"] = b.error;
        d["visibility_error"] = b.visibilityError;
        slices.append(d);
    }
    py::dict r;
    r["visibility"] = vis;
    r["matrix"] = m;
    r["error"] = T.E_rr;
    r["visibility_error"] = T.visibilityError;
    r["alpha_min"] = T.alpha_min;
    r["sub_blockers"] = T.subBlockers;
    r["resolution"] = T.n;
    r["fft_size"] = T.fftSize;
    r["rasterizer"] = rasterizerName(T.rasterizer);
    r["times"] = times;
    r["frame"] = frame;
    r["window"] = window;
    r["slices"] = slices;
    r["contact"] = plan.contact;
    return r;
}

// The sun's texture (convolution/sun_shadow.h): the engine's result keys that mean the same for it.
py::dict sunShadowTexture(const py::object& direction, double angle, const py::object& receiver,
                          const py::object& blockers, const py::object& resolution, double eMax, int nMax,
                          int minResolution, int maxResolution, double depthTolerance, bool contactSlabs) {
    F64 d = asDoubles(direction, "direction", {3});
    SunDesc sun{{d.data()[0], d.data()[1], d.data()[2]}, angle};
    ReceiverDesc rec;
    rec.points = points(asDoubles(receiver, "receiver", {-1, 3}));
    if (rec.points.size() < 3) throw py::value_error("receiver must have at least 3 vertices");
    std::vector<BlockerTriangle> tris;
    {
        F64 b = asDoubles(blockers, "blockers", {-1, 3, 3});
        tris.resize(b.shape(0));
        const double* p = b.data();
        for (size_t t = 0; t < tris.size(); ++t)
            for (int k = 0; k < 3; ++k) tris[t][k] = {p[9 * t + 3 * k], p[9 * t + 3 * k + 1], p[9 * t + 3 * k + 2]};
    }
    ConvolutionSettings s;
    if (!resolution.is_none()) {
        s.resolution = resolution.cast<int>();
        if (s.resolution < 1) throw py::value_error("resolution must be a positive int or None");
    }
    s.e_max = eMax;
    s.n_max = nMax;
    s.minResolution = minResolution;
    s.maxResolution = maxResolution;
    s.depthTolerance = depthTolerance;
    s.contactSlabs = contactSlabs;
    SoftShadowTexture T;
    {
        py::gil_scoped_release nogil;
        T = computeSunShadow(sun, tris, rec, s);
    }
    F32 vis({T.n, T.n});
    std::copy(T.visibility.begin(), T.visibility.end(), vis.mutable_data());
    F64 m({4, 4});
    std::copy(T.matrix.begin(), T.matrix.end(), m.mutable_data());
    py::dict times;
    times["raster_ms"] = T.times.rasterMs;
    times["fft_ms"] = T.times.fftMs;
    times["rest_ms"] = T.times.restMs;
    py::dict r;
    r["visibility"] = vis;
    r["matrix"] = m;
    r["error"] = T.E_rr;
    r["alpha_min"] = T.alpha_min;
    r["sub_blockers"] = T.subBlockers;
    r["resolution"] = T.n;
    r["fft_size"] = T.fftSize;
    r["times"] = times;
    return r;
}

py::array_t<float> lookup(const py::dict& result, const py::object& pts) {
    if (!result.contains("visibility") || !result.contains("matrix"))
        throw py::value_error("result must be a dict returned by soft_shadow_texture");
    F32 vis = F32::ensure(result["visibility"]);
    if (!vis || vis.ndim() != 2 || vis.shape(0) != vis.shape(1) || vis.shape(0) < 1)
        throw py::value_error("result['visibility'] must be a square 2-D array");
    F64 m = asDoubles(result["matrix"], "result['matrix']", {4, 4});
    F64 p = asDoubles(pts, "points", {-1, 3});
    SoftShadowTexture T;
    T.n = static_cast<int>(vis.shape(0));
    T.visibility.assign(vis.data(), vis.data() + vis.size());
    std::copy(m.data(), m.data() + 16, T.matrix.begin());
    std::vector<Vec3> P = points(p);
    py::array_t<float> out(static_cast<py::ssize_t>(P.size()));
    float* o = out.mutable_data();
    for (size_t i = 0; i < P.size(); ++i) o[i] = lookupVisibility(T, P[i]);
    return out;
}

// Best-of-`repeats` time in ms of the three transforms of one slice (kernel r2c, blocker r2c,
// product c2r) at FFT size n, with the plans the link uses: the floor a link is compared with.
double benchFftFloor(int n, int repeats) {
    py::gil_scoped_release nogil;
    FftConvolver fft(n);
    RealImage a = fft.makeImage(), b = fft.makeImage();
    Spectrum sa = fft.makeSpectrum(), sb = fft.makeSpectrum();
    for (size_t i = 0; i < a.size(); ++i) a[i] = b[i] = static_cast<float>((i * 2654435761u) % 997) * 1e-3f;
    double best = HUGE_VAL;
    for (int r = 0; r < std::max(1, repeats) + 1; ++r) {
        auto t0 = std::chrono::steady_clock::now();
        fft.forward(a, sa);
        fft.forward(b, sb);
        fft.inverse(sa, a);
        double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
        if (r > 0) best = std::min(best, ms);  // the first run warms the caches
    }
    return best;
}

// Best-of-`repeats` ms to rasterize 2-D triangles (m x 3 x 2) on a size x size grid over
// [lo, hi]^2, and the coverage image of the last run.
py::tuple benchRasterize(const py::object& triangles, double lo, double hi, int size, const std::string& rasterizer,
                         int supersample, int repeats) {
    F64 t = asDoubles(triangles, "triangles", {-1, 3, 2});
    if (size < 1 || !(hi > lo)) throw py::value_error("need size >= 1 and hi > lo");
    PolygonSet ps;
    const double* d = t.data();
    for (py::ssize_t k = 0; k < t.shape(0); ++k) {
        Vec2 v[3] = {{d[6 * k], d[6 * k + 1]}, {d[6 * k + 2], d[6 * k + 3]}, {d[6 * k + 4], d[6 * k + 5]}};
        ps.add(v, 3);
    }
    PixelGrid g{lo, lo, (hi - lo) / size, size, size};
    F32 img({size, size});
    std::vector<float> buf(static_cast<size_t>(size) * size);
    double best = HUGE_VAL;
    {
        py::gil_scoped_release nogil;
        auto r = makeRasterizer(parseRasterizerKind(rasterizer), supersample);
        for (int i = 0; i < std::max(1, repeats) + 1; ++i) {
            auto t0 = std::chrono::steady_clock::now();
            r->rasterize(ps, g, buf.data());
            double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
            if (i > 0) best = std::min(best, ms);  // the first run may create a context
        }
    }
    std::copy(buf.begin(), buf.end(), img.mutable_data());
    return py::make_tuple(best, img);
}

}  // namespace

void bindConvolution(py::module_& m) {
    m.def("soft_shadow_texture", &softShadowTexture, py::arg("source"), py::arg("receiver"), py::arg("blockers"),
          py::arg("resolution") = py::none(), py::arg("emission_image") = py::none(), py::arg("e_max") = 2.0,
          py::arg("n_max") = 8, py::arg("rasterizer") = "auto", py::arg("supersample") = 4,
          py::arg("direction") = "auto", py::arg("min_resolution") = 16, py::arg("max_resolution") = 512,
          py::arg("depth_tolerance") = 1e-3, py::arg("contact_slabs") = true,
          R"doc(Soft shadow texture by convolution (Soler & Sillion 1998); see docs/convolution.md.

source: (k, 3) planar polygon, k >= 3, any winding; it emits towards the receiver.
receiver: (j, 3) receiver polygon (or points bounding a group of receivers), j >= 3.
blockers: (m, 3, 3) triangles; m may be 0 (full light).
resolution: texels per side, or None to choose it from alpha_min.
emission_image: optional (h, w) non-negative image over the source's own (s, t) parametrisation
  (s along the first edge v0->v1, t along normal x s; rows are t, columns s, over the polygon's
  bounding rectangle in that frame).
e_max: target error E_rr in texels; n_max: most sub-blockers (depth slabs).
rasterizer: "auto" (= "span"), "span" or "osmesa".
contact_slabs: a blocker reaching the receiver is cut into contact sub-blockers (clipped slabs, the
  contact slab with the blocker's cross-section); False plans it like any other blocker.
Returns a dict: visibility (n, n) float32 indexed [t, s]; matrix (4, 4) float64 with
M @ [x, y, z, 1] = [s q, t q, 0, q]; error (E_rr, texels); visibility_error (predicted max |dV|);
alpha_min; sub_blockers; resolution; fft_size; times {raster_ms, fft_ms, rest_ms}; frame; window;
slices; contact. Raises ValueError for bad input or a configuration the convolution cannot handle.)doc");
    m.def("sun_shadow_texture", &sunShadowTexture, py::arg("direction"), py::arg("angle"), py::arg("receiver"),
          py::arg("blockers"), py::arg("resolution") = py::none(), py::arg("e_max") = 2.0, py::arg("n_max") = 8,
          py::arg("min_resolution") = 16, py::arg("max_resolution") = 512, py::arg("depth_tolerance") = 1e-3,
          py::arg("contact_slabs") = true,
          R"doc(A SUN lamp's soft shadow texture by convolution (convolution/sun_shadow.h, docs/convolution.md).

direction: (3,) the way the light travels; angle: the sun's angular diameter in radians, in (0, 179 degrees].
receiver: (j, 3) receiver polygon, j >= 3; blockers: (m, 3, 3) triangles.
resolution: texels per side, or None for 1/16 of the narrowest penumbra within min/max_resolution.
Returns a dict: visibility (n, n) float32, the cosine-weighted visible share of the sun's disk; matrix;
error (E_rr in half the narrowest penumbra); alpha_min; sub_blockers; resolution; fft_size; times.
Read it with lookup(). Raises ValueError for bad input or a configuration the convolution cannot handle.)doc");
    m.def("lookup", &lookup, py::arg("result"), py::arg("points"),
          "Visibility at 3-D points (m, 3) from a soft_shadow_texture result: bilinear, by central projection "
          "from the source centre, clamped to the edge texels; NaN for points not in front of the source centre.");
    m.def("fft_cost_constant", &fftCostConstant,
          "C of the link time model t = (2 + 2N) C n^2 log2 n, in seconds (calibrated on first call).");
    m.def("predicted_seconds", &predictedSeconds, py::arg("n"), py::arg("N"),
          "Predicted time of a convolution link with FFT size n and N sub-blockers.");
    m.def("bench_fft_floor_ms", &benchFftFloor, py::arg("n"), py::arg("repeats") = 5,
          "Best time (ms) of the three FFTs of one slice at size n (diagnostics for the benchmark).");
    m.def("bench_rasterize", &benchRasterize, py::arg("triangles"), py::arg("lo"), py::arg("hi"), py::arg("size"),
          py::arg("rasterizer") = "span", py::arg("supersample") = 4, py::arg("repeats") = 5,
          "Best time (ms) and coverage image of rasterizing 2-D triangles (diagnostics for the benchmark).");
}

}  // namespace penumbra::python
