// Progress of a long per-object loop on stderr (issue 15): every `period` seconds one line
//   shapesim-measure: measured 1200 / 3015 objects (40%), 310 per s, 3.9 s so far, about 5.9 s left
// from whichever thread finishes an object then. Shown with -v, or when stderr is a terminal
// (never under -q); the data on stdout are untouched, so outputs stay bit-identical.
#pragma once

#include "app/log.hpp"

#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <mutex>
#include <string>

namespace shapesim::app {

/// "0.42 s", "12 s", "3 min 05 s", "2 h 07 min": a duration as a person reads it.
inline std::string human_duration(double seconds) {
    char text[48];
    if (!(seconds >= 0.0) || !std::isfinite(seconds)) return "?";
    if (seconds < 10.0) {
        std::snprintf(text, sizeof text, "%.2g s", seconds);
    } else if (seconds < 60.0) {
        std::snprintf(text, sizeof text, "%.0f s", seconds);
    } else if (seconds < 3600.0) {
        const long s = std::lround(seconds);
        std::snprintf(text, sizeof text, "%ld min %02ld s", s / 60, s % 60);
    } else {
        const long m = std::lround(seconds / 60.0);
        std::snprintf(text, sizeof text, "%ld h %02ld min", m / 60, m % 60);
    }
    return text;
}

class Progress {
public:
    /// `verb` and `noun` make the line ("measured", "objects"); `total` the loop's length.
    /// `period` ≤ 0, -q, or (at the default verbosity) a stderr that is not a terminal: silent.
    Progress(const Log& log, std::string verb, std::string noun, std::size_t total,
             double period = 2.0)
        : log_(log),
          verb_(std::move(verb)),
          noun_(std::move(noun)),
          total_(total),
          period_(period),
          start_(std::chrono::steady_clock::now()),
          last_(start_) {
        enabled_ = period > 0.0 &&
                   (log.verbosity() == Verbosity::verbose ||
                    (log.verbosity() == Verbosity::normal && isatty(STDERR_FILENO)));
    }

    /// One more done (any thread); prints when `period` has passed since the last line.
    void done_one() {
        const std::size_t done = ++done_;
        if (!enabled_) return;
        const auto now = std::chrono::steady_clock::now();
        std::unique_lock<std::mutex> lock(mutex_, std::try_to_lock);
        if (!lock.owns_lock() || std::chrono::duration<double>(now - last_).count() < period_)
            return;
        last_ = now;
        ++lines_;
        const double elapsed = std::chrono::duration<double>(now - start_).count();
        const double rate = elapsed > 0.0 ? double(done) / elapsed : 0.0;
        const double left = rate > 0.0 ? double(total_ - std::min(done, total_)) / rate : -1.0;
        char percent[16];
        std::snprintf(percent, sizeof percent, "%.0f%%",
                      total_ ? 100.0 * double(done) / double(total_) : 100.0);
        char per_second[32];
        std::snprintf(per_second, sizeof per_second, "%.3g", rate);
        log_.info(verb_, " ", done, " / ", total_, " ", noun_, " (", percent, "), ", per_second,
                  " per s, ", human_duration(elapsed), " so far, about ", human_duration(left),
                  " left");
    }

    std::size_t done() const { return done_; }
    /// Progress lines printed so far.
    long lines() const { return lines_; }
    bool enabled() const { return enabled_; }

private:
    const Log& log_;
    std::string verb_, noun_;
    std::size_t total_;
    double period_;
    bool enabled_ = false;
    std::atomic<std::size_t> done_{0};
    std::mutex mutex_;
    std::chrono::steady_clock::time_point start_, last_;
    long lines_ = 0;
};

}  // namespace shapesim::app
