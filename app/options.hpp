// Command-line options for the shapesim programs, on Boost.ProgramOptions.
//
// The common options are declared once here (Gnuastro's commonopts.h) and mean the same in
// every program: -h/--help, --version, -o/--output, -q/--quiet, -v/--verbose, -j/--threads,
// --seed, --like, --config FILE, --print-params. A program picks which apply (`Common` bits;
// --help and --version always do), adds its own options in titled groups (Input, Output,
// Algorithm, Performance) with units in the help and range checks beside the declaration
// (`in_range` notifiers, so bad values fail while parsing), and reads the values back.
//
// --config FILE reads `name = value` lines (Boost's config syntax, `#` comments); the command
// line wins over the file. --print-params prints the effective values in that syntax, for
// pipelines to store and replay. Usage errors are po::error: app::run_main prints them as
// `program: message (see --help)` and exits 2.
#pragma once

#include "app/log.hpp"

#include <boost/program_options.hpp>

#include <cstdint>
#include <functional>
#include <memory>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

namespace shapesim::app {

namespace po = boost::program_options;

/// The common options a program offers (bits for ProgramOptions).
struct Common {
    static constexpr unsigned none = 0;
    static constexpr unsigned output = 1u << 0;        ///< -o/--output FILE (else stdout)
    static constexpr unsigned quiet = 1u << 1;         ///< -q/--quiet
    static constexpr unsigned verbose = 1u << 2;       ///< -v/--verbose
    static constexpr unsigned threads = 1u << 3;       ///< -j/--threads N
    static constexpr unsigned seed = 1u << 4;          ///< --seed N
    static constexpr unsigned like = 1u << 5;          ///< --like IMAGE
    static constexpr unsigned config = 1u << 6;        ///< --config FILE
    static constexpr unsigned print_params = 1u << 7;  ///< --print-params
    static constexpr unsigned all = (1u << 8) - 1;
};

/// Values of the common options after parsing.
struct CommonValues {
    std::string output;                       ///< -o; empty when not given
    Verbosity verbosity = Verbosity::normal;  ///< -q / -v
    int threads = 1;                          ///< -j, resolved (0 → hardware threads)
    std::uint64_t seed = 0;                   ///< --seed
    bool seed_given = false;
    std::string like;    ///< --like; empty when not given
    std::string config;  ///< --config; empty when not given
    /// The output's target for AtomicTextFile: -o's file, or "-" (stdout) when not given.
    std::string output_or_stdout() const { return output.empty() ? "-" : output; }
};

/// A notifier that throws po::error unless lo ≤ value ≤ hi, e.g.
/// `po::value<double>(&p.thresh)->notifier(in_range("detect-thresh", 0.0, 100.0))`.
template <class T>
std::function<void(const T&)> in_range(const std::string& option, T lo, T hi) {
    return [=](const T& value) {
        if (!(value >= lo && value <= hi)) {
            std::ostringstream s;
            s << "--" << option << ": must be in [" << lo << ", " << hi << "], got " << value;
            throw po::error(s.str());
        }
    };
}

/// A program's option table, help text and parsed values.
class ProgramOptions {
public:
    /// @param program     e.g. "shapesim-detect"
    /// @param synopsis    usage after the name, e.g. "[OPTION]... IMAGE"
    /// @param description purpose and a short example, printed by --help
    /// @param common      which Common options apply
    ProgramOptions(std::string program, std::string synopsis, std::string description,
                   unsigned common);

    /// The options group titled `title` (made on first use; groups print in that order,
    /// before the common options).
    po::options_description& group(const std::string& title);
    /// Options that --help does not list (positional arguments are declared here).
    po::options_description& hidden() { return hidden_; }
    /// Bind positional arguments to option `name` (−1: any number).
    void positional(const std::string& name, int max_count);
    /// Text printed after the options by --help (examples, see-also).
    void epilog(std::string text) { epilog_ = std::move(text); }
    /// Keep unknown options and extra arguments instead of failing (placeholder programs).
    void allow_unregistered() { allow_unregistered_ = true; }
    /// Accept `old_name` as another name of option `name`, on the command line (--old,
    /// --old=value) and in --config files, for a release after a rename: the value goes to
    /// `name`, --help lists the old name, and a warning on stderr (unless -q) gives the new one.
    void alias(const std::string& old_name, const std::string& name);

    /// Parse the command line (then --config). Returns false when the program's work is done:
    /// --help, --version or --print-params was printed on stdout. Throws po::error for usage
    /// errors, Error for an unreadable --config file.
    bool parse(int argc, const char* const argv[]);

    const po::variables_map& values() const { return values_; }
    const CommonValues& common() const { return common_; }
    /// True when option `name` was given on the command line or in --config.
    bool given(const std::string& name) const;
    /// The old names used in this run, as (old, new) pairs (see alias()).
    const std::vector<std::pair<std::string, std::string>>& aliases_used() const {
        return aliases_used_;
    }
    /// Unknown options and arguments (only with allow_unregistered()).
    const std::vector<std::string>& unrecognized() const { return unrecognized_; }

    /// The --help text.
    std::string help() const;
    /// The effective settings as (name, value text) pairs, in declaration order, one pair per
    /// value (the --help, --version, --config, --print-params options excluded). For
    /// --print-params and for the provenance keywords of FITS outputs (HIERARCH).
    std::vector<std::pair<std::string, std::string>> settings() const;
    /// The --print-params text: a comment line, then `name = value` per setting.
    std::string params() const;

private:
    void declare_common(unsigned common);
    void read_config(const std::string& path);
    std::string renamed(const std::string& name);
    void resolve_common();
    po::options_description all_options(bool for_config) const;

    std::string program_, synopsis_, description_, epilog_;
    // unique_ptr: references returned by group() stay valid as groups are added.
    std::vector<std::pair<std::string, std::unique_ptr<po::options_description>>> groups_;
    po::options_description common_options_{"Common options"};
    po::options_description hidden_;
    po::positional_options_description positional_;
    po::variables_map values_;
    CommonValues common_;
    std::string seed_text_;
    std::vector<std::string> unrecognized_;
    std::vector<std::pair<std::string, std::string>> aliases_, aliases_used_;
    bool allow_unregistered_ = false;
};

/// The shortest text that reads back as the same double (30, 0.2, 31.542503180159343), as
/// --print-params writes values.
std::string double_text(double v);

/// `help` with every 17-digit double default, e.g. (=0.96999999999999997), printed as the
/// shortest text that reads back as the same double, (=0.97) (Boost prints the former).
std::string defaults_as_written(const std::string& help);

/// The items of a comma-separated option value ("a, b,,c" → a b c): spaces dropped, empty
/// items skipped.
std::vector<std::string> split_list(const std::string& list);

/// NAME=FILE option values (--compare, --compare-sky) split at the first '='; po::error
/// naming `option` for a value without a name or a file.
std::vector<std::pair<std::string, std::string>> named_files(const std::vector<std::string>& specs,
                                                             const std::string& option);

/// The version line printed by --version: "<program> (shapesim) <shapesim::version()>".
std::string version_line(const std::string& program);

}  // namespace shapesim::app
