// A standard link: the receiver gathers F * B_source. The estimate's spread is kept so that a later
// refinement pass can re-judge the link with the source's new radiosity without casting rays again.
#pragma once
#include <cstdint>
#include <mutex>
#include <utility>
#include <vector>

namespace penumbra {

struct Link {
    int receiver = -1;
    int source = -1;
    float Fmean = 0;   // unoccluded receiver-averaged form factor
    float Fspread = 0; // max - min of the point form factors over the receiver (a cluster link's: 0, or
                       // negative while its V is a first pass's provisional estimate, refiner.cpp)
    float V = 1;       // visible fraction of the rays
    // Receiver-averaged form factor times visibility. Computed, not stored: links are the solve's
    // largest array, 20 bytes each instead of 24.
    float F() const { return Fmean * V; }
    bool partial() const { return V > 0 && V < 1; }
};

// Two kinds of cluster link are marked by their Fspread (a cluster link's spread is otherwise 0):
// a reflector's first-pass link whose V is a provisional estimate (Refiner::estimateCluster), and a link
// from a near cluster source into an element that takes the source's light face by face, each face with
// its own form factor and visible share (Refiner::shareSourceByFaces; the weights are in a
// ClusterFaceVisibility keyed by the receiving element).
inline constexpr float kProvisional = -1.0f;
inline constexpr float kSourceShared = -2.0f;
inline bool provisional(const Link& l) { return l.Fspread == kProvisional; }
inline bool sourceShared(const Link& l) { return l.Fspread == kSourceShared; }

// Per partly seen link into a cluster that the refiner kept instead of opening: each face's own visible share
// of the source, in the cluster's polygon order, keyed by (receiver cluster key, source key). Kept in one
// float array with a sorted index: as a std::map of vectors it took ~140 bytes per link besides the shares
// (a fifth of the 20k office's peak memory at epsilon 0.002). A second table holds the links from near cluster
// sources into elements (kSourceShared): one weight per face of the source, keyed by (receiving element's key,
// source cluster's key).
class ClusterFaceVisibility {
public:
    // Thread-safe. A pair recorded again (a later refinement pass) replaces its shares at the next finish().
    void record(uint64_t receiverKey, uint64_t sourceKey, const float* share, size_t n);
    // Sorts the index (on `threads` threads) and drops replaced shares; call before find() once a refinement
    // pass is done.
    void finish(int threads = 1);
    // The pair's shares (one per face of the receiving cluster, or of the source cluster in the second table), or null.
    const float* find(uint64_t receiverKey, uint64_t sourceKey) const;
    bool empty() const { return index_.empty(); }
    size_t size() const { return index_.size(); }

private:
    // 24 bytes: offsets grow with the recording order, which therefore needs no field of its own.
    struct Entry {
        uint64_t receiver, source;
        uint32_t offset;  // into shares_
        uint32_t count;
    };
    std::mutex mutex_;
    std::vector<Entry> index_;
    std::vector<float> shares_;
    bool sorted_ = true;
};

}  // namespace penumbra
