// An estimate of the bake's error, per object and overall, from the solution's own terms (no baker
// reports one). Each link contributes what it leaves unresolved on its receiver, as an RMS over the
// receiver's points:
//   - the form factor's variation across the receiver, rho B Fspread / sqrt(12) (a linear ramp's RMS
//     about its mean). With the final gather the emitters' share of B is evaluated exactly at every
//     point, so only the reflected part (B - E) counts;
//   - a partly visible transfer's shadow inside the receiver, rho B F sqrt(V (1 - V)) (the RMS of a
//     0/1 visibility about its mean V), halved for the blend between leaves, and the 16-ray sampling
//     error of V itself, sqrt(V (1 - V) / n);
//   - a cluster transfer, at most its flux bound (by construction rho * bound <= epsilon), / sqrt(12).
// A leaf adds the squares of its links and of its ancestors' and clusters' links, and the solver's
// remaining relative error times its radiosity. The figure is the area-weighted RMS of that over the
// area-weighted RMS radiance, the measure the benchmark reports per texel against Cycles. Convolution
// links are taken as exact here (their own error, E_rr, is reported beside).
#pragma once
#include <vector>

#include "hierarchy/element.h"
#include "solve/link.h"
#include "solve/settings.h"

namespace penumbra {

struct ErrorEstimate {
    double overall = 0;
    std::vector<double> perObject;  // by object index; -1 for an object that receives nothing
};

ErrorEstimate estimateError(const Hierarchy& h, const std::vector<Link>& links, const Settings& s,
                            double residual);

}  // namespace penumbra
