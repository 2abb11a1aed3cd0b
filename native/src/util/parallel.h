// Splits of [0, n) over threads: each index is processed by exactly one thread and no result depends on
// which one, so outputs are bit-identical for any thread count.
#pragma once
#include <algorithm>
#include <atomic>
#include <exception>
#include <iterator>
#include <thread>
#include <vector>

namespace penumbra {

inline int resolveThreads(int requested) {
    int hw = int(std::thread::hardware_concurrency());
    return requested > 0 ? requested : std::max(1, hw);
}

// Runs work(t) on threads t = 0 .. threads-1 and rethrows the first error once all have joined.
template <class W>
void runThreads(int threads, W&& work) {
    std::vector<std::thread> pool;
    std::vector<std::exception_ptr> errors(threads);
    for (int t = 0; t < threads; ++t)
        pool.emplace_back([&, t] {
            try {
                work(t);
            } catch (...) {
                errors[t] = std::current_exception();
            }
        });
    for (auto& th : pool) th.join();
    for (auto& e : errors)
        if (e) std::rethrow_exception(e);
}

// body(begin, end, threadIndex). Blocks of `grain` indices are dealt round-robin so uneven work
// (links near the light refine deeper) spreads over threads.
template <class F>
void parallelFor(size_t n, int threads, size_t grain, F&& body) {
    threads = std::max(1, threads);
    if (threads == 1 || n <= grain) {
        body(size_t(0), n, 0);
        return;
    }
    runThreads(threads, [&](int t) {
        for (size_t b = size_t(t) * grain; b < n; b += size_t(threads) * grain) body(b, std::min(n, b + grain), t);
    });
}

// As parallelFor, but each thread takes the next block when it is done with its last: for a few hundred
// items whose costs differ by orders of magnitude (the refinement's root pairs), where a fixed deal left one
// core idle while the other finished its share. Which thread takes a block varies from run to run, so the
// body must write only what belongs to its indices (per-index outputs), never per-thread sums.
template <class F>
void parallelForDynamic(size_t n, int threads, size_t grain, F&& body) {
    threads = std::max(1, threads);
    grain = std::max<size_t>(1, grain);
    if (threads == 1 || n <= grain) {
        body(size_t(0), n, 0);
        return;
    }
    std::atomic<size_t> next{0};
    runThreads(threads, [&](int t) {
        try {
            for (size_t b = next.fetch_add(grain); b < n; b = next.fetch_add(grain)) body(b, std::min(n, b + grain), t);
        } catch (...) {
            next = n;  // the others stop at their next block
            throw;
        }
    });
}

// std::sort of [first, last) on up to `threads` threads: runs of about equal length sorted each on its own,
// then merged pairwise. The result is a sorted sequence, so where `less` orders any two distinct elements
// (as the links' (receiver, source) keys, which are never repeated) it is std::sort's to the bit. Below
// kSerialSort elements, or on one thread, it is std::sort.
template <class It, class Less>
void parallelSort(It first, It last, int threads, Less less) {
    constexpr ptrdiff_t kSerialSort = 1 << 15;
    const ptrdiff_t n = std::distance(first, last);
    threads = std::max(1, threads);
    if (threads == 1 || n < kSerialSort) {
        std::sort(first, last, less);
        return;
    }
    int runs = 1;
    while (runs < threads && n / (2 * runs) >= kSerialSort / 2) runs *= 2;  // a power of two, for pairwise merges
    std::vector<It> bound(size_t(runs) + 1);
    for (int k = 0; k <= runs; ++k) bound[size_t(k)] = first + n * k / runs;
    parallelForDynamic(size_t(runs), threads, 1, [&](size_t b, size_t e, int) {
        for (size_t k = b; k < e; ++k) std::sort(bound[k], bound[k + 1], less);
    });
    for (int width = 1; width < runs; width *= 2) {
        const size_t merges = size_t(runs / (2 * width));
        parallelForDynamic(merges, threads, 1, [&](size_t b, size_t e, int) {
            for (size_t m = b; m < e; ++m) {
                size_t lo = m * 2 * size_t(width);
                std::inplace_merge(bound[lo], bound[lo + size_t(width)], bound[lo + 2 * size_t(width)], less);
            }
        });
    }
}

}  // namespace penumbra
