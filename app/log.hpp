// A tiny stderr logger for the programs (STYLE (b) "stderr"): stdout is data only; human text
// goes to stderr, one line per call, prefixed with the program name:
//   shapesim-detect: 163 sources in 0.41 s
//   shapesim-detect: warning: 3 stamps touch the image edge
// `-q` leaves only errors (printed by app::run_main), `-v` adds per-object lines. Warnings keep
// the exit code; what downstream must act on belongs in a record's `flags`, not here.
#pragma once

#include <sys/resource.h>

#include <chrono>
#include <iostream>
#include <sstream>
#include <string>

namespace shapesim::app {

/// How much a program says on stderr (`-q`, default, `-v`).
enum class Verbosity { quiet, normal, verbose };

class Log {
public:
    /// @param program    prefix of every line, e.g. "shapesim-detect"
    /// @param verbosity  from the common options
    /// @param out        sink (stderr; a string stream in tests)
    explicit Log(std::string program, Verbosity verbosity = Verbosity::normal,
                 std::ostream& out = std::cerr)
        : program_(std::move(program)),
          verbosity_(verbosity),
          out_(&out),
          start_(std::chrono::steady_clock::now()) {}

    /// A stage line (counts, elapsed time); silent under -q. Arguments are streamed.
    template <class... Args>
    void info(const Args&... args) const {
        if (verbosity_ != Verbosity::quiet) emit("", args...);
    }
    /// A per-object line, shown only under -v.
    template <class... Args>
    void verbose(const Args&... args) const {
        if (verbosity_ == Verbosity::verbose) emit("", args...);
    }
    /// A warning ("program: warning: …"); silent under -q.
    template <class... Args>
    void warn(const Args&... args) const {
        if (verbosity_ != Verbosity::quiet) emit("warning: ", args...);
    }

    /// Seconds since the logger was made (for "… in 0.41 s").
    double elapsed() const {
        return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    }
    Verbosity verbosity() const { return verbosity_; }
    /// The process's peak resident memory so far, MiB (for "peak memory" in a stage line).
    static double peak_memory_mib() {
        rusage usage{};
        getrusage(RUSAGE_SELF, &usage);
        return double(usage.ru_maxrss) / 1024.0;  // Linux reports KiB
    }

private:
    // Build the whole line first and write it with one call, so lines from several threads
    // do not interleave mid-line.
    template <class... Args>
    void emit(const char* kind, const Args&... args) const {
        std::ostringstream line;
        line << program_ << ": " << kind;
        (line << ... << args);
        line << '\n';
        const std::string text = line.str();
        out_->write(text.data(), std::streamsize(text.size()));
        out_->flush();
    }

    std::string program_;
    Verbosity verbosity_;
    std::ostream* out_;
    std::chrono::steady_clock::time_point start_;
};

}  // namespace shapesim::app
