#include "bindings.h"

namespace penumbra::python {
// Filled in by the convolution stage (issue 4).
void bindConvolution(pybind11::module_& m) {}
}  // namespace penumbra::python
