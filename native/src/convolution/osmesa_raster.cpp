#include "convolution/osmesa_raster.h"

#if PENUMBRA_HAVE_OSMESA

// Prototypes are only needed for decltype(); no gl* symbol is ever referenced (see header).
#define GL_GLEXT_PROTOTYPES 1
#include <GL/osmesa.h>

#include <algorithm>
#include <stdexcept>
#include <string>
#include <memory>
#include <vector>

#include <GL/glext.h>

namespace penumbra {

namespace {

// decltype() of a gl* symbol is unevaluated, so the binary keeps no reference to it.
#define PENUMBRA_GL_FUNCS(X)                                                                        \
    X(GetString) X(GetIntegerv) X(Viewport) X(ClearColor) X(Clear) X(DrawArrays) X(Finish)          \
    X(ReadPixels) X(PixelStorei) X(GetError) X(Enable) X(Disable)                                   \
    X(GenBuffers) X(BindBuffer) X(BufferData) X(GenVertexArrays) X(BindVertexArray)                 \
    X(EnableVertexAttribArray) X(VertexAttribPointer) X(CreateShader) X(ShaderSource)               \
    X(CompileShader) X(GetShaderiv) X(CreateProgram) X(AttachShader) X(LinkProgram)                 \
    X(GetProgramiv) X(UseProgram) X(GetUniformLocation) X(Uniform2f) X(GenFramebuffers)            \
    X(BindFramebuffer) X(GenRenderbuffers) X(BindRenderbuffer) X(RenderbufferStorage)              \
    X(RenderbufferStorageMultisample) X(FramebufferRenderbuffer) X(CheckFramebufferStatus)         \
    X(BlitFramebuffer) X(DeleteRenderbuffers)

struct GlTable {
#define PENUMBRA_DECLARE(name) decltype(&::gl##name) name = nullptr;
    PENUMBRA_GL_FUNCS(PENUMBRA_DECLARE)
#undef PENUMBRA_DECLARE
    void load() {
#define PENUMBRA_LOAD(name)                                                                         \
    name = reinterpret_cast<decltype(name)>(OSMesaGetProcAddress("gl" #name));                      \
    if (!name) throw std::runtime_error("OSMesaGetProcAddress failed for gl" #name);
        PENUMBRA_GL_FUNCS(PENUMBRA_LOAD)
#undef PENUMBRA_LOAD
    }
};

const char* kVertex = R"(#version 330 core
layout(location = 0) in vec2 pos;      // pixel units of the grid
uniform vec2 scale;                    // 2 / (width, height)
void main() { gl_Position = vec4(pos * scale - 1.0, 0.0, 1.0); }
)";
const char* kFragment = R"(#version 330 core
out vec4 color;
void main() { color = vec4(1.0); }
)";

struct ThreadContext {
    OSMesaContext ctx = nullptr;
    unsigned char dummy[4 * 4 * 4] = {};
    GlTable gl;
    GLuint program = 0, vao = 0, vbo = 0, msFbo = 0, msRb = 0, fbo = 0, rb = 0;
    GLint scaleLoc = -1;
    int width = 0, height = 0, samples = 0, maxSamples = 0;

    ThreadContext() {
        const int attribs[] = {OSMESA_FORMAT, OSMESA_RGBA, OSMESA_DEPTH_BITS, 0,
                               OSMESA_PROFILE, OSMESA_CORE_PROFILE,
                               OSMESA_CONTEXT_MAJOR_VERSION, 3, OSMESA_CONTEXT_MINOR_VERSION, 3, 0};
        ctx = OSMesaCreateContextAttribs(attribs, nullptr);
        if (!ctx) throw std::runtime_error("OSMesaCreateContextAttribs failed (GL 3.3 core)");
        // The default framebuffer is never drawn to: all work happens in our own framebuffers.
        if (!OSMesaMakeCurrent(ctx, dummy, GL_UNSIGNED_BYTE, 4, 4))
            throw std::runtime_error("OSMesaMakeCurrent failed");
        gl.load();
        program = gl.CreateProgram();
        for (auto [type, src] : {std::pair<GLenum, const char*>{GL_VERTEX_SHADER, kVertex},
                                 {GL_FRAGMENT_SHADER, kFragment}}) {
            GLuint sh = gl.CreateShader(type);
            gl.ShaderSource(sh, 1, &src, nullptr);
            gl.CompileShader(sh);
            GLint ok = 0;
            gl.GetShaderiv(sh, GL_COMPILE_STATUS, &ok);
            if (!ok) throw std::runtime_error("OSMesa shader compilation failed");
            gl.AttachShader(program, sh);
        }
        gl.LinkProgram(program);
        GLint ok = 0;
        gl.GetProgramiv(program, GL_LINK_STATUS, &ok);
        if (!ok) throw std::runtime_error("OSMesa shader link failed");
        scaleLoc = gl.GetUniformLocation(program, "scale");
        gl.GenVertexArrays(1, &vao);
        gl.BindVertexArray(vao);
        gl.GenBuffers(1, &vbo);
        gl.BindBuffer(GL_ARRAY_BUFFER, vbo);
        gl.EnableVertexAttribArray(0);
        gl.VertexAttribPointer(0, 2, GL_FLOAT, GL_FALSE, 0, nullptr);
        gl.GetIntegerv(GL_MAX_SAMPLES, &maxSamples);
        gl.GenFramebuffers(1, &msFbo);
        gl.GenFramebuffers(1, &fbo);
    }
    ~ThreadContext() {
        if (ctx) OSMesaDestroyContext(ctx);
    }

    void resize(int w, int h, int wantSamples) {
        int s = std::max(1, std::min(wantSamples, maxSamples));
        if (w == width && h == height && s == samples) return;
        if (msRb) gl.DeleteRenderbuffers(1, &msRb);
        if (rb) gl.DeleteRenderbuffers(1, &rb);
        gl.GenRenderbuffers(1, &msRb);
        gl.BindRenderbuffer(GL_RENDERBUFFER, msRb);
        gl.RenderbufferStorageMultisample(GL_RENDERBUFFER, s, GL_RGBA8, w, h);
        gl.BindFramebuffer(GL_FRAMEBUFFER, msFbo);
        gl.FramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, msRb);
        if (gl.CheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
            throw std::runtime_error("OSMesa multisample framebuffer incomplete");
        gl.GenRenderbuffers(1, &rb);
        gl.BindRenderbuffer(GL_RENDERBUFFER, rb);
        gl.RenderbufferStorage(GL_RENDERBUFFER, GL_RGBA8, w, h);
        gl.BindFramebuffer(GL_FRAMEBUFFER, fbo);
        gl.FramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, rb);
        if (gl.CheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
            throw std::runtime_error("OSMesa resolve framebuffer incomplete");
        width = w;
        height = h;
        samples = s;
    }
};

ThreadContext& threadContext() {
    thread_local std::unique_ptr<ThreadContext> tc;
    if (!tc) tc = std::make_unique<ThreadContext>();
    else if (OSMesaGetCurrentContext() != tc->ctx)
        OSMesaMakeCurrent(tc->ctx, tc->dummy, GL_UNSIGNED_BYTE, 4, 4);
    return *tc;
}

}  // namespace

OSMesaRasterizer::OSMesaRasterizer(int samples) : samples_(samples) {
    if (samples < 1) throw std::invalid_argument("OSMesa samples must be >= 1");
}

std::string OSMesaRasterizer::rendererName() {
    ThreadContext& tc = threadContext();
    const GLubyte* s = tc.gl.GetString(GL_RENDERER);
    return s ? reinterpret_cast<const char*>(s) : "";
}

void OSMesaRasterizer::rasterize(const PolygonSet& polys, const PixelGrid& g, float* out) {
    ThreadContext& tc = threadContext();
    GlTable& gl = tc.gl;
    // llvmpipe offers 4x MSAA at most; more samples come from rendering k x k times larger and
    // box-filtering on the CPU.
    const int ms = std::max(1, std::min(samples_, tc.maxSamples));
    int k = 1;
    while (k * k * ms < samples_) ++k;
    const int W = g.width * k, H = g.height * k;
    tc.resize(W, H, ms);
    samplesUsed_ = tc.samples * k * k;

    std::vector<float> tris;
    tris.reserve(static_cast<size_t>(polys.vertices.size()) * 2 * 3);
    for (int k = 0; k < polys.size(); ++k) {
        int s = polys.start[k], e = polys.start[k + 1];
        for (int i = s + 1; i + 1 < e; ++i)
            for (int idx : {s, i, i + 1}) {
                tris.push_back(static_cast<float>((polys.vertices[idx].x - g.u0) / g.p));
                tris.push_back(static_cast<float>((polys.vertices[idx].y - g.v0) / g.p));
            }
    }
    gl.BindFramebuffer(GL_FRAMEBUFFER, tc.msFbo);
    gl.Viewport(0, 0, W, H);
    gl.ClearColor(0, 0, 0, 0);
    gl.Clear(GL_COLOR_BUFFER_BIT);
    if (!tris.empty()) {
        gl.UseProgram(tc.program);
        gl.Uniform2f(tc.scaleLoc, 2.0f / g.width, 2.0f / g.height);
        gl.BindVertexArray(tc.vao);
        gl.BindBuffer(GL_ARRAY_BUFFER, tc.vbo);
        gl.BufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(tris.size() * sizeof(float)), tris.data(),
                      GL_STREAM_DRAW);
        gl.DrawArrays(GL_TRIANGLES, 0, static_cast<GLsizei>(tris.size() / 2));
    }
    gl.BindFramebuffer(GL_READ_FRAMEBUFFER, tc.msFbo);
    gl.BindFramebuffer(GL_DRAW_FRAMEBUFFER, tc.fbo);
    gl.BlitFramebuffer(0, 0, W, H, 0, 0, W, H, GL_COLOR_BUFFER_BIT, GL_NEAREST);
    gl.BindFramebuffer(GL_READ_FRAMEBUFFER, tc.fbo);
    std::vector<unsigned char> px(static_cast<size_t>(W) * H);
    gl.PixelStorei(GL_PACK_ALIGNMENT, 1);
    // Row 0 of a GL framebuffer is its bottom row, which is j = 0 here as well (v grows upwards).
    gl.ReadPixels(0, 0, W, H, GL_RED, GL_UNSIGNED_BYTE, px.data());
    if (gl.GetError() != GL_NO_ERROR) throw std::runtime_error("OSMesa rasterization raised a GL error");
    if (k == 1) {
        for (size_t i = 0; i < px.size(); ++i) out[i] = px[i] * (1.0f / 255.0f);
        return;
    }
    const float norm = 1.0f / (255.0f * k * k);
    for (int j = 0; j < g.height; ++j)
        for (int i = 0; i < g.width; ++i) {
            unsigned acc = 0;
            for (int b = 0; b < k; ++b) {
                const unsigned char* row = px.data() + static_cast<size_t>(j * k + b) * W + i * k;
                for (int a = 0; a < k; ++a) acc += row[a];
            }
            out[static_cast<size_t>(j) * g.width + i] = acc * norm;
        }
}

}  // namespace penumbra

#else  // built without OSMesa (Debian sid's Mesa has none): the class exists so callers and tests still link

#include <stdexcept>
#include <string>

namespace penumbra {

namespace {
[[noreturn]] void noOSMesa() {
    throw std::runtime_error(
        "this build has no OSMesa (Mesa 25.1 and later ship none); use the span rasterizer (rasterizer='span')");
}
}  // namespace

OSMesaRasterizer::OSMesaRasterizer(int samples) : samples_(samples) { noOSMesa(); }
std::string OSMesaRasterizer::rendererName() { noOSMesa(); }
void OSMesaRasterizer::rasterize(const PolygonSet&, const PixelGrid&, float*) { noOSMesa(); }

}  // namespace penumbra

#endif
