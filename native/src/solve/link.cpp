#include "solve/link.h"

#include "util/parallel.h"

#include <algorithm>
#include <limits>
#include <stdexcept>
#include <tuple>

namespace penumbra {

void ClusterFaceVisibility::record(uint64_t receiverKey, uint64_t sourceKey, const float* share, size_t n) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (shares_.size() + n > std::numeric_limits<uint32_t>::max())
        throw std::length_error("ClusterFaceVisibility: more than 2^32 face shares");
    index_.push_back({receiverKey, sourceKey, uint32_t(shares_.size()), uint32_t(n)});
    shares_.insert(shares_.end(), share, share + n);
    sorted_ = false;
}

void ClusterFaceVisibility::finish(int threads) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (sorted_) return;
    // The offset makes every entry's key distinct, so the order is the same on any number of threads.
    parallelSort(index_.begin(), index_.end(), threads, [](const Entry& a, const Entry& b) {
        return std::tie(a.receiver, a.source, a.offset) < std::tie(b.receiver, b.source, b.offset);
    });
    // Keep the last recording of each pair. Its shares move down over the dropped ones in place, in the
    // order they were recorded (a fresh copy of both arrays was the peak of a pass at 10k polygons).
    constexpr uint32_t kDropped = std::numeric_limits<uint32_t>::max();
    std::vector<uint32_t> byOffset;
    for (size_t i = 0; i < index_.size(); ++i) {
        Entry& e = index_[i];
        if (i + 1 < index_.size() && index_[i + 1].receiver == e.receiver && index_[i + 1].source == e.source)
            e.count = kDropped;
        else
            byOffset.push_back(uint32_t(i));
    }
    parallelSort(byOffset.begin(), byOffset.end(), threads,
              [&](uint32_t a, uint32_t b) { return index_[a].offset < index_[b].offset; });
    size_t w = 0;
    for (uint32_t i : byOffset) {
        Entry& e = index_[i];
        if (w != e.offset)  // w < offset: std::copy may move a range down over itself, not onto its own start
            std::copy(shares_.begin() + ptrdiff_t(e.offset), shares_.begin() + ptrdiff_t(e.offset + e.count),
                      shares_.begin() + ptrdiff_t(w));
        e.offset = uint32_t(w);
        w += e.count;
    }
    shares_.resize(w);
    index_.erase(std::remove_if(index_.begin(), index_.end(), [&](const Entry& e) { return e.count == kDropped; }),
                 index_.end());
    sorted_ = true;
}

const float* ClusterFaceVisibility::find(uint64_t receiverKey, uint64_t sourceKey) const {
    if (!sorted_) throw std::logic_error("ClusterFaceVisibility::find before finish()");
    auto it = std::lower_bound(index_.begin(), index_.end(), std::make_pair(receiverKey, sourceKey),
                               [](const Entry& e, const std::pair<uint64_t, uint64_t>& k) {
                                   return std::tie(e.receiver, e.source) < std::tie(k.first, k.second);
                               });
    if (it == index_.end() || it->receiver != receiverKey || it->source != sourceKey) return nullptr;
    return shares_.data() + it->offset;
}

}  // namespace penumbra
