// A standard link: the receiver gathers F * B_source. The estimate's spread is kept so that a later
// refinement pass can re-judge the link with the source's new radiosity without casting rays again.
#pragma once
#include <cstdint>

namespace penumbra {

struct Link {
    int receiver = -1;
    int source = -1;
    float F = 0;       // receiver-averaged form factor times visibility
    float Fmean = 0;   // unoccluded receiver-averaged form factor
    float Fspread = 0; // max - min of the point form factors over the receiver
    float V = 1;       // visible fraction of the rays
    bool partial() const { return V > 0 && V < 1; }
};

}  // namespace penumbra
