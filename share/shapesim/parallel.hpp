// One loop over independent items on several threads, for the programs' per-object work
// (decompose, render, measure). Items are handed out one at a time, so uneven costs balance;
// results go into slots indexed by the item, so the output order never depends on the threads.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <thread>
#include <vector>

namespace shapesim {

/// Call work(k, t) once for every k in [0, count), on min(threads, count) threads (t = 0 is
/// the calling thread; a per-thread workspace can be indexed by t). `work` must not throw:
/// catch inside and record the failure in item k's slot.
template <class Work>
void parallel_for(std::size_t count, int threads, const Work& work) {
    const int n = std::max(1, std::min<int>(threads, int(std::min<std::size_t>(count, 1 << 20))));
    std::atomic<std::size_t> next{0};
    auto run = [&](int t) {
        for (std::size_t k = next++; k < count; k = next++) work(k, t);
    };
    std::vector<std::thread> pool;
    for (int t = 1; t < n; ++t) pool.emplace_back(run, t);
    run(0);
    for (auto& thread : pool) thread.join();
}

}  // namespace shapesim
