#include "bindings.h"

PYBIND11_MODULE(_native, m) {
    m.doc() = "Penumbra's native solver: hierarchical radiosity with convolution soft-shadow textures.";
    m.attr("python_version") = PENUMBRA_PYTHON_VERSION;
    penumbra::python::bindSolver(m);
    penumbra::python::bindConvolution(m);
}
