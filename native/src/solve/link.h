// A standard link: the receiver gathers F * B_source. The estimate's spread is kept so that a later
// refinement pass can re-judge the link with the source's new radiosity without casting rays again.
#pragma once
#include <cstdint>
#include <map>
#include <mutex>
#include <utility>
#include <vector>

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

// Per partly seen link into a cluster that the refiner kept instead of opening: each face's own visible share
// of the source, in the cluster's polygon order, keyed by (receiver cluster key, source key).
struct ClusterFaceVisibility {
    std::mutex mutex;
    std::map<std::pair<uint64_t, uint64_t>, std::vector<float>> shares;
};

}  // namespace penumbra
