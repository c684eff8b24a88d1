// One loop over independent items on several threads, for the programs' per-object work
// (decompose, render, measure), and image rows in bands. Items are handed out one at a time,
// so uneven costs balance; results go into slots indexed by the item, so the output order
// never depends on the threads.
#pragma once

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <exception>
#include <mutex>
#include <optional>
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

/// work(first, last) for the rows [first, last) of `rows` split into min(threads, rows)
/// contiguous bands, one thread a band (the calling thread the first): for image rows whose
/// work is even, where handing out one row at a time would cost more than it balances.
/// `work` must not throw.
template <class Work>
void parallel_bands(long rows, int threads, const Work& work) {
    const int parts = int(std::max<long>(1, std::min<long>(threads, rows)));
    const auto band = [&](int k) {
        return std::make_pair(rows * k / parts, rows * (k + 1) / parts);
    };
    std::vector<std::thread> pool;
    for (int k = 1; k < parts; ++k)
        pool.emplace_back([&, k] {
            const auto [first, last] = band(k);
            work(first, last);
        });
    const auto [first, last] = band(0);
    work(first, last);
    for (auto& t : pool) t.join();
}

/// produce(k) for every k in [0, count) on min(threads, count) threads, and consume(k, item)
/// in order k = 0, 1, …, each by whichever thread holds the next item (one at a time), so
/// consuming (writing a file) overlaps producing. At most threads + 1 items wait at once, so
/// memory is bounded by the items in flight. produce and consume may throw: no new item is
/// started after the first exception, which is rethrown here once every thread has stopped.
template <class Produce, class Consume>
void parallel_in_order(std::size_t count, int threads, const Produce& produce,
                       const Consume& consume) {
    using Item = decltype(produce(std::size_t(0)));
    const std::size_t n = std::clamp<std::size_t>(count, 1, std::size_t(std::max(threads, 1)));
    const std::size_t in_flight = n + 1;
    std::mutex m;
    std::condition_variable cv;
    std::vector<std::optional<Item>> ready(count);
    std::size_t next_take = 0, next_consume = 0;
    bool consuming = false;
    std::exception_ptr error;
    auto fail = [&](std::unique_lock<std::mutex>& lock) {
        if (!lock.owns_lock()) lock.lock();
        if (!error) error = std::current_exception();
        cv.notify_all();
    };
    auto run = [&] {
        std::unique_lock<std::mutex> lock(m);
        for (;;) {
            cv.wait(lock, [&] {
                return error || next_take >= count || next_take < next_consume + in_flight;
            });
            if (error || next_take >= count) return;
            const std::size_t k = next_take++;
            lock.unlock();
            try {
                Item item = produce(k);
                lock.lock();
                ready[k].emplace(std::move(item));
            } catch (...) {
                fail(lock);
                return;
            }
            // Consume what is next in order, unless another thread is doing so.
            while (!consuming && !error && next_consume < count && ready[next_consume]) {
                consuming = true;
                const std::size_t c = next_consume;
                Item item = std::move(*ready[c]);
                ready[c].reset();
                lock.unlock();
                try {
                    consume(c, std::move(item));
                } catch (...) {
                    fail(lock);
                    consuming = false;
                    return;
                }
                lock.lock();
                consuming = false;
                ++next_consume;
                cv.notify_all();
            }
        }
    };
    std::vector<std::thread> pool;
    for (std::size_t t = 1; t < n; ++t) pool.emplace_back(run);
    run();
    for (auto& thread : pool) thread.join();
    if (error) std::rethrow_exception(error);
}

}  // namespace shapesim
