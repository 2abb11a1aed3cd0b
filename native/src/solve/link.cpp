#include "solve/link.h"

#include <algorithm>
#include <stdexcept>
#include <tuple>

namespace penumbra {

void ClusterFaceVisibility::record(uint64_t receiverKey, uint64_t sourceKey, const float* share, size_t n) {
    std::lock_guard<std::mutex> lock(mutex_);
    index_.push_back({receiverKey, sourceKey, shares_.size(), uint32_t(n), uint32_t(index_.size())});
    shares_.insert(shares_.end(), share, share + n);
    sorted_ = false;
}

void ClusterFaceVisibility::finish() {
    std::lock_guard<std::mutex> lock(mutex_);
    if (sorted_) return;
    std::sort(index_.begin(), index_.end(), [](const Entry& a, const Entry& b) {
        return std::tie(a.receiver, a.source, a.order) < std::tie(b.receiver, b.source, b.order);
    });
    // Keep the last recording of each pair, its shares moved into a fresh array in index order.
    std::vector<Entry> kept;
    std::vector<float> shares;
    for (size_t i = 0; i < index_.size(); ++i) {
        const Entry& e = index_[i];
        if (i + 1 < index_.size() && index_[i + 1].receiver == e.receiver && index_[i + 1].source == e.source)
            continue;
        kept.push_back({e.receiver, e.source, shares.size(), e.count, uint32_t(kept.size())});
        shares.insert(shares.end(), shares_.begin() + ptrdiff_t(e.offset),
                      shares_.begin() + ptrdiff_t(e.offset + e.count));
    }
    kept.shrink_to_fit();
    shares.shrink_to_fit();
    index_.swap(kept);
    shares_.swap(shares);
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
