// Each stage that is reachable from Python registers its functions here; module.cpp calls them all.
#pragma once
#include <pybind11/pybind11.h>

namespace penumbra::python {
void bindSolver(pybind11::module_& m);
void bindConvolution(pybind11::module_& m);
}  // namespace penumbra::python
