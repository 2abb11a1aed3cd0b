// Progress and cancellation cross the native boundary as one callback that returns false to stop,
// the contract of Embree's progress monitor. The solver checks it between units of work and unwinds
// by throwing Cancelled, so no stage ever hands on a half-built result.
#pragma once
#include <stdexcept>
#include <string>

namespace penumbra {

class Progress {
public:
    virtual ~Progress() = default;
    // stage: a short name ("refine", "visibility", "solve", "bake"); fraction in [0, 1] of that stage.
    virtual bool update(const char* stage, double fraction) { return true; }
};

struct Cancelled : std::runtime_error {
    Cancelled() : std::runtime_error("cancelled by the user") {}
};

// Bad input: the message names the object so the user can find it.
struct InputError : std::invalid_argument {
    using std::invalid_argument::invalid_argument;
};

// The scene would need more memory or work than a budget in Settings allows. Thrown before the
// allocation that would exceed it; the message names the budget and how to stay within it.
struct BudgetExceeded : InputError {
    using InputError::InputError;
};

inline void checkProgress(Progress* p, const char* stage, double fraction) {
    if (p && !p->update(stage, fraction)) throw Cancelled();
}

}  // namespace penumbra
