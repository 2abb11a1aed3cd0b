// Progress and cancellation cross the native boundary as one callback that returns false to stop,
// the contract of Embree's progress monitor. The solver checks it between units of work and unwinds
// by throwing Cancelled, so no stage ever hands on a half-built result.
#pragma once
#include <atomic>
#include <chrono>

#include "util/error.h"

namespace penumbra {

class Progress {
public:
    virtual ~Progress() = default;
    // stage: a short name ("refine", "visibility", "solve", "bake"); fraction in [0, 1] of that stage.
    virtual bool update(const char* stage, double fraction) { return true; }
};

inline void checkProgress(Progress* p, const char* stage, double fraction) {
    if (p && !p->update(stage, fraction)) throw Cancelled();
}

// Cancellation for work spread over threads: every thread checks the shared flag often, and thread 0
// (the only one that may call back into the caller, who may hold a lock such as the GIL) polls the
// callback at most every 50 ms, so Esc is honoured within a fraction of a second even when single
// work items are long.
class ProgressPoll {
public:
    ProgressPoll(Progress* p, const char* stage) : progress_(p), stage_(stage) {}
    bool stop(int thread, double fraction) {
        if (cancel_.load(std::memory_order_relaxed)) return true;
        if (thread != 0 || !progress_) return false;
        auto now = std::chrono::steady_clock::now();
        if (now - last_ < std::chrono::milliseconds(50)) return false;
        last_ = now;
        if (!progress_->update(stage_, fraction)) cancel_ = true;
        return cancel_;
    }
    void cancel() { cancel_ = true; }
    bool cancelled() const { return cancel_; }

private:
    Progress* progress_;
    const char* stage_;
    std::atomic<bool> cancel_{false};
    std::chrono::steady_clock::time_point last_{};
};

}  // namespace penumbra
