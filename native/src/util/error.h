// The errors the solver throws across its API (after pbrt's util/error.h: one place for them). The
// Python module maps them (native/python/bind_solver.cpp): InputError -> ValueError, BudgetExceeded ->
// _native.BudgetExceeded (a ValueError), Cancelled -> _native.Cancelled. Anything else thrown inside is a
// bug, not a user's mistake.
#pragma once
#include <stdexcept>

namespace penumbra {

// The user stopped the solve through Progress (util/progress.h).
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

}  // namespace penumbra
