// Program plumbing: app/options (common options, --config, --print-params, range checks),
// app/run_main (exceptions → one stderr line and an exit code) and app/log.
#include "decompose/options.hpp"
#include "app/detection_run.hpp"
#include "app/log.hpp"
#include "app/options.hpp"
#include "app/progress.hpp"
#include "app/run_main.hpp"
#include "smooth/source_fields.hpp"
#include "shapesim/error.hpp"
#include "shapesim/version.hpp"

#include <gtest/gtest.h>

#include <unistd.h>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <sstream>
#include <thread>
#include <vector>

using namespace shapesim;
namespace po = boost::program_options;

namespace {
// A small program's option table: one Algorithm option with a range, one input positional.
struct Table {
    double thresh = 0.0;
    app::ProgramOptions options{"shapesim-test", "[OPTION]... IMAGE", "Test the option plumbing.",
                                app::Common::all};
    Table() {
        options.group("Algorithm")
            .add_options()("detect-thresh",
                           po::value<double>(&thresh)->default_value(1.3)->notifier(
                               app::in_range("detect-thresh", 0.0, 100.0)),
                           "detection threshold, sigma (paper: 1.3)");
        options.group("Input").add_options()("weight", po::value<std::string>(), "weight map");
        options.hidden().add_options()("image", po::value<std::string>()->required());
        options.positional("image", 1);
    }
    bool parse(std::vector<const char*> args) {
        args.insert(args.begin(), "shapesim-test");
        return options.parse(int(args.size()), args.data());
    }
};

std::string usage_error(std::vector<const char*> args) {
    Table t;
    try {
        t.parse(std::move(args));
    } catch (const po::error& e) {
        return e.what();
    }
    return "no error";
}

std::string temp_file(const std::string& text) {
    char pattern[] = "/tmp/shapesim-app-XXXXXX";
    const int fd = mkstemp(pattern);
    close(fd);
    std::ofstream(pattern) << text;
    return pattern;
}
}  // namespace

TEST(ProgramOptions, CommonAndProgramOptions) {
    Table t;
    ASSERT_TRUE(t.parse({"hdf.fits", "--detect-thresh", "2.5", "-o", "out.fits", "-j", "3",
                         "--seed", "18446744073709551615", "--like", "hdf.fits", "-q"}));
    EXPECT_EQ(t.thresh, 2.5);
    EXPECT_EQ(t.options.values()["image"].as<std::string>(), "hdf.fits");
    const app::CommonValues& c = t.options.common();
    EXPECT_EQ(c.output, "out.fits");
    EXPECT_EQ(c.threads, 3);
    EXPECT_EQ(c.seed, 18446744073709551615ull);
    EXPECT_TRUE(c.seed_given);
    EXPECT_EQ(c.like, "hdf.fits");
    EXPECT_EQ(c.verbosity, app::Verbosity::quiet);
    EXPECT_TRUE(t.options.given("detect-thresh"));
    EXPECT_FALSE(t.options.given("weight"));

    Table defaults;
    ASSERT_TRUE(defaults.parse({"hdf.fits", "-j0"}));
    EXPECT_EQ(defaults.thresh, 1.3);
    EXPECT_GE(defaults.options.common().threads, 1);  // 0 = one per hardware thread
    EXPECT_EQ(defaults.options.common().seed, 0u);
    EXPECT_FALSE(defaults.options.common().seed_given);
    EXPECT_EQ(defaults.options.common().verbosity, app::Verbosity::normal);
    EXPECT_FALSE(defaults.options.given("detect-thresh"));
}

TEST(ProgramOptions, NegativeNumbersAreValues) {
    // "--shear 0.01 -0.02": Boost alone reads -0.02 as an unknown short option.
    std::vector<double> shear;
    double kappa = 0.0;
    app::ProgramOptions options{"shapesim-test", "[OPTION]...", "Negative values.", app::Common::all};
    options.group("Lensing").add_options()
        ("shear", po::value(&shear)->multitoken(), "G1 G2")
        ("kappa", po::value(&kappa), "convergence");
    std::vector<const char*> args{"shapesim-test", "--shear", "0.01", "-0.02", "--kappa", "-1e-3", "-q"};
    ASSERT_TRUE(options.parse(int(args.size()), args.data()));
    EXPECT_EQ(shear, (std::vector<double>{0.01, -0.02}));
    EXPECT_EQ(kappa, -1e-3);
    EXPECT_EQ(options.common().verbosity, app::Verbosity::quiet);
    // A short option is still one, and a negative number where none is wanted is still refused.
    EXPECT_EQ(usage_error({"hdf.fits", "-5"}), "too many positional options have been specified on the command line");
}

TEST(ProgramOptions, UsageErrors) {
    EXPECT_EQ(usage_error({"hdf.fits", "--detect-thresh", "-1"}),
              "--detect-thresh: must be in [0, 100], got -1");
    EXPECT_EQ(usage_error({"hdf.fits", "--seed", "-1"}),
              "--seed: must be an integer in [0, 2^64 - 1], got '-1'");
    EXPECT_EQ(usage_error({"hdf.fits", "--seed", "18446744073709551616"}),
              "--seed: must be an integer in [0, 2^64 - 1], got '18446744073709551616'");
    EXPECT_EQ(usage_error({"hdf.fits", "-q", "-v"}), "--quiet and --verbose exclude each other");
    EXPECT_EQ(usage_error({"hdf.fits", "-j", "-2"}), "--threads: must be in [0, 4096], got -2");
    EXPECT_EQ(usage_error({"hdf.fits", "--no-such-option"}),
              "unrecognised option '--no-such-option'");
    EXPECT_EQ(usage_error({"a.fits", "b.fits"}),
              "too many positional options have been specified on the command line");
    EXPECT_NE(usage_error({}).find("image"), std::string::npos);  // the required input
    EXPECT_NE(usage_error({"hdf.fits", "--detect-thresh", "high"}).find("detect-thresh"),
              std::string::npos);
}

// shapesim-decompose's options parsed into DecomposeSettings.
struct DecomposeTable {
    app::DecomposeSettings s;
    app::ProgramOptions options{"shapesim-decompose", "[OPTION]...", "Test.",
                                app::Common::like | app::Common::threads};
    explicit DecomposeTable(std::vector<const char*> args) {
        s.declare(options);
        args.insert(args.begin(), "shapesim-decompose");
        EXPECT_TRUE(options.parse(int(args.size()), args.data()));
    }
};

// The options checked together; the PSF mode's target scale and fit options.
TEST(DecomposeSettings, ChecksAndPsfModeValues) {
    const auto check_error = [&](std::vector<const char*> args) -> std::string {
        DecomposeTable t(std::move(args));
        try {
            t.s.check();
        } catch (const po::error& e) {
            return e.what();
        }
        return "no error";
    };
    EXPECT_EQ(check_error({"--n-max-min", "5", "--n-max-cap", "3"}),
              "--n-max-min must not exceed --n-max-cap");
    EXPECT_EQ(check_error({"--ids", "1,2"}), "--ids needs --models");
    EXPECT_EQ(check_error({"--white-noise", "--noise-model", "sky.jsonl"}),
              "--white-noise and a noise model exclude each other");
    EXPECT_EQ(check_error({"--white-noise", "--band-noise-model", "f435w=sky.jsonl"}),
              "--white-noise and a noise model exclude each other");

    DecomposeTable round({"--round-lowest"});
    round.s.check();
    EXPECT_FALSE(round.s.fit.elliptical);
    DecomposeTable sheared({});
    sheared.s.check();
    EXPECT_TRUE(sheared.s.fit.elliptical);
    EXPECT_EQ(sheared.s.fit.n_max_cap, 15);

    DecomposeTable psf({"--pixel-scale", "0.06", "--psf-residual", "0.002", "--psf-n-max-cap", "9"});
    EXPECT_EQ(psf.s.psf_target_scale(psf.options), 0.06);
    EXPECT_EQ(psf.s.psf_fit().residual_target, 0.002);
    EXPECT_EQ(psf.s.psf_fit().n_max_cap, 9);
    DecomposeTable no_scale({});
    EXPECT_THROW(no_scale.s.psf_target_scale(no_scale.options), po::error);

    // A per-band option without NAME=FILE is a usage error.
    DecomposeTable band({"--band-psf", "nofile"});
    try {
        band.s.job_reader(band.options);
        ADD_FAILURE() << "--band-psf nofile was accepted";
    } catch (const po::error& e) {
        EXPECT_EQ(std::string(e.what()), "--band-psf takes NAME=FILE, got 'nofile'");
    }
}

TEST(ProgramOptions, HelpAndVersionStopTheProgram) {
    Table t;
    testing::internal::CaptureStdout();
    EXPECT_FALSE(t.parse({"--help"}));  // even without the required IMAGE
    const std::string help = testing::internal::GetCapturedStdout();
    EXPECT_EQ(help.rfind("Usage: shapesim-test [OPTION]... IMAGE\nTest the option plumbing.", 0),
              0u);
    EXPECT_LT(help.find("Algorithm:"), help.find("Input:"));  // groups in declaration order
    EXPECT_LT(help.find("Input:"), help.find("Common options:"));
    EXPECT_NE(help.find("(=1.3)"), std::string::npos);
    EXPECT_NE(help.find("--print-params"), std::string::npos);
    EXPECT_EQ(help.find("--image"), std::string::npos);  // hidden

    Table v;
    testing::internal::CaptureStdout();
    EXPECT_FALSE(v.parse({"--version"}));
    EXPECT_EQ(testing::internal::GetCapturedStdout(),
              std::string("shapesim-test (shapesim) ") + shapesim::version() + "\n");
}

TEST(ProgramOptions, ConfigFileAndPrintParamsReplay) {
    const std::string config = temp_file(
        "# stored by a pipeline\n"
        "detect-thresh = 2.0\n"
        "seed = 7\n"
        "weight = w.fits\n");
    Table t;
    testing::internal::CaptureStdout();
    EXPECT_FALSE(
        t.parse({"hdf.fits", "--config", config.c_str(), "--seed", "9", "--print-params"}));
    const std::string params = testing::internal::GetCapturedStdout();
    EXPECT_EQ(t.thresh, 2.0);                // from the file
    EXPECT_EQ(t.options.common().seed, 9u);  // the command line wins
    EXPECT_NE(params.find("detect-thresh = 2\n"), std::string::npos) << params;
    EXPECT_NE(params.find("seed = 9\n"), std::string::npos);
    EXPECT_NE(params.find("weight = w.fits\n"), std::string::npos);
    EXPECT_NE(params.find("image = hdf.fits\n"), std::string::npos);
    EXPECT_NE(params.find("threads = 1\n"), std::string::npos);
    EXPECT_EQ(params.find("config ="), std::string::npos);  // the run, not a setting

    // The printed parameters are a config file that reproduces the run.
    const std::string replay = temp_file(params);
    Table again;
    ASSERT_TRUE(again.parse({"--config", replay.c_str()}));
    EXPECT_EQ(again.thresh, 2.0);
    EXPECT_EQ(again.options.common().seed, 9u);
    EXPECT_EQ(again.options.values()["image"].as<std::string>(), "hdf.fits");

    const std::string bad = temp_file("no-such-option = 1\n");
    EXPECT_EQ(usage_error({"hdf.fits", "--config", bad.c_str()}),
              bad + ": unrecognised option 'no-such-option'");
    Table missing;
    EXPECT_THROW(missing.parse({"hdf.fits", "--config", "/nonexistent.conf"}), Error);
    for (const auto& f : {config, replay, bad}) std::remove(f.c_str());
}

TEST(RunMain, ExceptionsBecomeOneLineAndAnExitCode) {
    const char* argv[] = {"prog"};
    const auto run = [&](app::ProgramBody body, std::string& err) {
        testing::internal::CaptureStderr();
        const int code = app::run_main(1, argv, "shapesim-x", body);
        err = testing::internal::GetCapturedStderr();
        return code;
    };
    std::string err;
    EXPECT_EQ(run([](int, const char* const*) { return 0; }, err), 0);
    EXPECT_EQ(err, "");
    EXPECT_EQ(run([](int, const char* const*) { return 3; }, err), 3);
    EXPECT_EQ(run(
                  [](int, const char* const*) -> int {
                      throw Error("must be > 0, got -0.3", "shapelets.jsonl", 42, "beta");
                  },
                  err),
              1);
    EXPECT_EQ(err, "shapesim-x: shapelets.jsonl:42: beta: must be > 0, got -0.3\n");
    EXPECT_EQ(run([](int, const char* const*) -> int { throw po::error("bad usage"); }, err), 2);
    EXPECT_EQ(err, "shapesim-x: bad usage (see --help)\n");
    EXPECT_EQ(run([](int, const char* const*) -> int { throw std::logic_error("oops"); }, err), 1);
    EXPECT_EQ(err, "shapesim-x: internal error: oops\n");
    EXPECT_EQ(run([](int, const char* const*) -> int { throw std::bad_alloc(); }, err), 1);
    EXPECT_EQ(err, "shapesim-x: out of memory\n");
    EXPECT_EQ(run([](int, const char* const*) -> int { throw 7; }, err), 1);
    EXPECT_EQ(err, "shapesim-x: internal error: unknown exception\n");
}

TEST(RunMain, Placeholder) {
    const auto run = [](std::vector<const char*> args, std::string& out, std::string& err) {
        args.insert(args.begin(), "shapesim-x");
        testing::internal::CaptureStdout();
        testing::internal::CaptureStderr();
        const int code = app::run_placeholder(int(args.size()), args.data(), "shapesim-x",
                                              "Do something useful.");
        out = testing::internal::GetCapturedStdout();
        err = testing::internal::GetCapturedStderr();
        return code;
    };
    std::string out, err;
    EXPECT_EQ(run({"--help"}, out, err), 0);
    EXPECT_NE(out.find("Do something useful."), std::string::npos);
    EXPECT_NE(out.find("NOT IMPLEMENTED YET"), std::string::npos);
    EXPECT_EQ(run({"--version"}, out, err), 0);
    EXPECT_EQ(out.rfind("shapesim-x (shapesim) ", 0), 0u);
    for (auto args : std::vector<std::vector<const char*>>{
             {}, {"in.fits"}, {"--weight", "w.fits", "x"}, {"-o", "out.fits"}}) {
        EXPECT_EQ(run(args, out, err), 2);
        EXPECT_EQ(out, "");
        EXPECT_EQ(err, "shapesim-x: not implemented yet (see --help)\n");
    }
}

TEST(Log, VerbosityLevels) {
    std::ostringstream normal, quiet, verbose;
    const app::Log n("shapesim-x", app::Verbosity::normal, normal);
    const app::Log q("shapesim-x", app::Verbosity::quiet, quiet);
    const app::Log v("shapesim-x", app::Verbosity::verbose, verbose);
    for (const app::Log* log : {&n, &q, &v}) {
        log->info(163, " sources in ", 0.5, " s");
        log->verbose("object ", 7);
        log->warn("3 stamps touch the edge");
    }
    EXPECT_EQ(normal.str(),
              "shapesim-x: 163 sources in 0.5 s\nshapesim-x: warning: 3 stamps touch the edge\n");
    EXPECT_EQ(quiet.str(), "");
    EXPECT_EQ(verbose.str(),
              "shapesim-x: 163 sources in 0.5 s\nshapesim-x: object 7\n"
              "shapesim-x: warning: 3 stamps touch the edge\n");
    EXPECT_GE(n.elapsed(), 0.0);
}

// Progress: with -v a line per period (0.05 s here) from whichever thread finishes then, the
// count right and never past the total; silent under -q, with no period, and (at the default
// verbosity) when stderr is not a terminal, as under the test runner. Durations read as a
// person says them.
TEST(Progress, PeriodicLinesOnlyWhenAsked) {
    EXPECT_EQ(app::human_duration(0.4242), "0.42 s");
    EXPECT_EQ(app::human_duration(12.3), "12 s");
    EXPECT_EQ(app::human_duration(185.0), "3 min 05 s");
    EXPECT_EQ(app::human_duration(7620.0), "2 h 07 min");
    EXPECT_EQ(app::human_duration(-1.0), "?");
    std::ostringstream verbose, quiet, normal;
    const app::Log v("shapesim-x", app::Verbosity::verbose, verbose);
    const app::Log q("shapesim-x", app::Verbosity::quiet, quiet);
    const app::Log n("shapesim-x", app::Verbosity::normal, normal);
    app::Progress pv(v, "measured", "objects", 40, 0.05), pq(q, "measured", "objects", 40, 0.05),
        pn(n, "measured", "objects", 40, 0.05), never(v, "measured", "objects", 40, 0.0);
    std::vector<std::thread> threads;
    for (int t = 0; t < 4; ++t)
        threads.emplace_back([&] {
            for (int i = 0; i < 10; ++i) {
                std::this_thread::sleep_for(std::chrono::milliseconds(10));
                for (app::Progress* p : {&pv, &pq, &pn, &never}) p->done_one();
            }
        });
    for (auto& t : threads) t.join();
    EXPECT_EQ(pv.done(), 40u);
    EXPECT_GE(pv.lines(), 1);
    EXPECT_LE(pv.lines(), 3);  // 0.1 s of work at 0.05 s a line
    EXPECT_NE(verbose.str().find("shapesim-x: measured "), std::string::npos) << verbose.str();
    EXPECT_NE(verbose.str().find(" / 40 objects ("), std::string::npos) << verbose.str();
    EXPECT_NE(verbose.str().find(" left\n"), std::string::npos) << verbose.str();
    EXPECT_EQ(quiet.str(), "");
    EXPECT_FALSE(pq.enabled());
    if (!isatty(STDERR_FILENO)) {  // as under make test and CI
        EXPECT_EQ(normal.str(), "");
    }
    EXPECT_EQ(never.lines(), 0);
}

// --help prints defaults as written (issue 18's "0.96999999999999997"): the shortest text that
// reads back as the same double; a description on the same line keeps its column; short
// numbers and non-numbers are untouched.
TEST(ProgramOptions, HelpPrintsDefaultsAsWritten) {
    EXPECT_EQ(app::defaults_as_written("  --star-threshold arg (=0.96999999999999997)\n"),
              "  --star-threshold arg (=0.97)\n");
    const std::string same_line = "  --k arg (=0.10000000000000001)  smoothing factor\n";
    const std::string tidy = app::defaults_as_written(same_line);
    EXPECT_EQ(tidy.rfind("  --k arg (=0.1) ", 0), 0u) << tidy;
    EXPECT_EQ(tidy.find("smoothing"), same_line.find("smoothing"));
    EXPECT_EQ(app::defaults_as_written("(=0.039800000000000002)\n(=1e-08) (=2.5) (=weight)"),
              "(=0.0398)\n(=1e-08) (=2.5) (=weight)");
    EXPECT_EQ(app::defaults_as_written("(=-2.3396949999999999)"), "(=-2.339695)");
}

TEST(ProgramOptions, OldNamesAreAliasesOfTheNewOnes) {
    const auto table = [] {
        auto t = std::make_unique<Table>();
        t->options.alias("threshold", "detect-thresh");
        t->options.alias("weight-map", "weight");
        return t;
    };
    {
        auto t = table();
        testing::internal::CaptureStderr();
        ASSERT_TRUE(t->parse({"hdf.fits", "--threshold", "2.5", "--weight-map=w.fits"}));
        const std::string warnings = testing::internal::GetCapturedStderr();
        EXPECT_EQ(t->thresh, 2.5);
        EXPECT_EQ(t->options.values()["weight"].as<std::string>(), "w.fits");
        EXPECT_TRUE(t->options.given("detect-thresh"));
        ASSERT_EQ(t->options.aliases_used().size(), 2u);
        EXPECT_EQ(warnings,
                  "shapesim-test: warning: --threshold is now --detect-thresh; the old name goes "
                  "in a later release\n"
                  "shapesim-test: warning: --weight-map is now --weight; the old name goes in a "
                  "later release\n");
    }
    {  // -q keeps stderr for errors; the new name warns of nothing
        auto t = table();
        testing::internal::CaptureStderr();
        ASSERT_TRUE(t->parse({"hdf.fits", "--threshold", "2", "-q"}));
        ASSERT_TRUE(table()->parse({"hdf.fits", "--detect-thresh", "2"}));
        EXPECT_EQ(testing::internal::GetCapturedStderr(), "");
    }
    {  // after "--" an argument is a value, even one spelled like an old name
        auto t = table();
        testing::internal::CaptureStderr();
        ASSERT_TRUE(t->parse({"--", "--threshold"}));
        testing::internal::GetCapturedStderr();
        EXPECT_EQ(t->options.values()["image"].as<std::string>(), "--threshold");
        EXPECT_EQ(t->thresh, 1.3);
    }
    {  // in a --config file too, and --print-params gives the new name
        const std::string config = temp_file("# old names\nthreshold = 3.5\n  weight-map=w.fits\n");
        auto t = table();
        testing::internal::CaptureStderr();
        testing::internal::CaptureStdout();
        EXPECT_FALSE(t->parse({"hdf.fits", "--config", config.c_str(), "--print-params"}));
        const std::string params = testing::internal::GetCapturedStdout();
        testing::internal::GetCapturedStderr();
        std::remove(config.c_str());
        EXPECT_EQ(t->thresh, 3.5);
        EXPECT_NE(params.find("detect-thresh = 3.5\n"), std::string::npos);
        EXPECT_NE(params.find("weight = w.fits\n"), std::string::npos);
        EXPECT_EQ(params.find("threshold ="), std::string::npos);
    }
    {  // old and new together are the same option given twice
        auto t = table();
        testing::internal::CaptureStderr();
        EXPECT_THROW(t->parse({"hdf.fits", "--threshold", "2", "--detect-thresh", "3"}), po::error);
        testing::internal::GetCapturedStderr();
    }
    {
        auto t = table();
        testing::internal::CaptureStdout();
        EXPECT_FALSE(t->parse({"--help"}));
        const std::string help = testing::internal::GetCapturedStdout();
        EXPECT_NE(help.find("Old option names, still accepted for this release:\n"
                            "  --threshold (now --detect-thresh)\n"
                            "  --weight-map (now --weight)\n"),
                  std::string::npos);
    }
}

// --like / --area / --field: one of them; --field's counted and shape-only fields, in order,
// with @MAG where given; malformed, repeated and shape-only-only specs are option errors.
TEST(SourceFields, ReadsTheFieldOptions) {
    const app::SourceFields none = app::read_source_fields("", std::nullopt, std::nullopt, {});
    EXPECT_TRUE(none.counted.empty() && none.images().empty());
    const app::SourceFields area = app::read_source_fields("", 2.5, std::nullopt, {});
    ASSERT_EQ(area.counted.size(), 1u);
    EXPECT_EQ(area.counted[0].area_arcmin2, 2.5);
    EXPECT_EQ(area.images(), std::vector<std::string>{""});
    app::SourceFields f = app::read_source_fields("", std::nullopt, std::nullopt,
                                                  {"a.fits=1.5", "s.fits=shapes", "b.fits=2@27"});
    ASSERT_EQ(f.counted.size(), 2u);
    EXPECT_EQ(f.completeness_given, (std::vector<bool>{false, true}));
    EXPECT_EQ(f.counted[1].completeness, 27.0);
    EXPECT_EQ(f.images(), (std::vector<std::string>{"a.fits", "b.fits", "s.fits"}));
    f.counted[0].mags = {25.0, 24.0};
    f.complete();
    EXPECT_EQ(f.counted[0].mags, (std::vector<double>{24.0, 25.0}));
    EXPECT_TRUE(std::isinf(f.counted[0].completeness));  // fewer than 10: no turnover
    EXPECT_EQ(f.counted[1].completeness, 27.0);
    for (const std::vector<std::string>& bad : {std::vector<std::string>{"a.fits"},
                                                {"=1"},
                                                {"a.fits=1x"},
                                                {"a.fits=-1"},
                                                {"a.fits=1@inf"},
                                                {"a.fits=1", "a.fits=shapes"},
                                                {"a.fits=shapes"}})
        EXPECT_THROW(app::read_source_fields("", std::nullopt, std::nullopt, bad), po::error)
            << bad[0];
    EXPECT_THROW(app::read_source_fields("", 1.0, std::nullopt, {"a.fits=1"}), po::error);
}

// A record found in a tile's window moves to the image's pixels: positions by the window's
// origin (integers stay integers), the id by the offset; other fields untouched.
TEST(DetectionRun, ShiftToImageMovesPositionsAndIds) {
    const TileWindow tile{{2049, 1, 4096, 2048}, {1793, 1, 4352, 2304}};
    Json r = {{"id", "17"}, {"x", 10.25}, {"y", 3.5}, {"x_peak", 10}, {"y_peak", 4},
              {"x_asym", 10.5}, {"y_asym", 3.25}, {"a", 2.0}, {"ra", 150.1}};
    app::shift_to_image(r, tile, 1000);
    EXPECT_EQ(r["id"], "1017");
    EXPECT_EQ(r["x"].get<double>(), 1802.25);
    EXPECT_EQ(r["y"].get<double>(), 3.5);
    EXPECT_TRUE(r["x_peak"].is_number_integer());
    EXPECT_EQ(r["x_peak"].get<long>(), 1802);
    EXPECT_EQ(r["y_peak"].get<long>(), 4);
    EXPECT_EQ(r["x_asym"].get<double>(), 1802.5);
    EXPECT_EQ(r["a"].get<double>(), 2.0);
    EXPECT_EQ(r["ra"].get<double>(), 150.1);
    // The first tile of an untiled run: nothing moves, bit for bit (−0 stays −0).
    Json same = {{"id", "3"}, {"x", -0.0}};
    app::shift_to_image(same, {{1, 1, 100, 100}, {1, 1, 100, 100}}, 0);
    EXPECT_TRUE(std::signbit(same["x"].get<double>()));
    EXPECT_EQ(same["id"], "3");
}
