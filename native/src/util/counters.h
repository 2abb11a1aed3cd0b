// Report counters, declared once where they are incremented (after pbrt's STAT_COUNTER, util/stats.h):
//
//     PENUMBRA_COUNTER(kRaysCast, "rays");   // at file scope in the .cpp that counts
//     counters_.add(kRaysCast, n);           // where it counts
//
// The declaration registers the name in a process-wide list of names when the program loads; the values
// live in a Counters object that each solve owns and hands to the stages that count, and the report takes
// every registered name from it (penumbra.cpp), so a new counter is one line and reaches Report::counts,
// the Python dict and the add-on without being copied by hand. A name "group/key" becomes
// report["group"]["key"] in Python.
//
// Why the values are per-solve rather than pbrt's process-global statics: the Python module releases the
// GIL, so two solves can run at once in one process; statics, even reset at each solve's start, would mix
// their counts. The counters are relaxed atomics (refiner threads share them): a sum of integers does not
// depend on the order of its terms, so every count is the same for any thread count. Every registered
// counter appears in every report, 0 when its stage did not run (convolution off: convolution_tried = 0).
#pragma once
#include <atomic>
#include <cstddef>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace penumbra {

using CounterId = int;

namespace detail {
// Every name declared with PENUMBRA_COUNTER, in registration order (which differs between builds:
// only names, never indices, leave the process). Filled during static initialisation.
inline std::vector<std::string>& counterNames() {
    static std::vector<std::string> names;
    return names;
}
// The id of `name`, registering it on first use; one name declared in two files is one counter.
inline CounterId registerCounter(const char* name) {
    auto& names = counterNames();
    for (size_t i = 0; i < names.size(); ++i)
        if (names[i] == name) return CounterId(i);
    names.emplace_back(name);
    return CounterId(names.size() - 1);
}
}  // namespace detail

// Declares a counter at namespace scope: `id` is its CounterId, `name` its key in the report.
#define PENUMBRA_COUNTER(id, name) static const ::penumbra::CounterId id = ::penumbra::detail::registerCounter(name)

// One solve's values of every registered counter. Construct it after static initialisation (any time in
// main or later); add() is safe from any thread.
class Counters {
public:
    Counters() : size_(detail::counterNames().size()), values_(new std::atomic<size_t>[size_]) {
        for (size_t i = 0; i < size_; ++i) values_[i].store(0, std::memory_order_relaxed);
    }
    void add(CounterId id, size_t n = 1) { values_[size_t(id)].fetch_add(n, std::memory_order_relaxed); }
    size_t value(CounterId id) const { return values_[size_t(id)].load(std::memory_order_relaxed); }
    // Name -> value of every counter; read it once the threads that count have joined.
    std::map<std::string, size_t> values() const {
        std::map<std::string, size_t> out;
        const auto& names = detail::counterNames();
        for (size_t i = 0; i < size_; ++i) out[names[i]] = value(CounterId(i));
        return out;
    }

private:
    size_t size_;
    std::unique_ptr<std::atomic<size_t>[]> values_;
};

}  // namespace penumbra
