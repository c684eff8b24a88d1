// Detection benchmarks: run time, the error it buys, and SExtractor's time on the same image.
//   BM_DetectHdf           detect_sources on the shipped 512² HDF-N F814W cut with its weight
//                          map, default (SExtractor-named) options.
//                          objects       detections
//                          cat_matched   fraction of the shipped SExtractor catalogue's objects
//                                        with MAG_BEST + 22.08 < 28 that have a detection within
//                                        1 px (its X_IMAGE is +1.00 px off the image grid: fixed
//                                        here before matching)
//   BM_DetectSynthetic/N   detect_sources on an N×N synthetic field (test_support: elliptical
//                          Gaussian galaxies and Gaussian stars of known position and flux on a
//                          jittered grid, white noise; built once, outside the timed loop).
//                          objects       detections
//                          true_objects  objects in the field
//                          completeness  fraction of the true objects with S/N > 10 that have a
//                                        detection within 1.5 px
//                          median_err_px median distance of those matches
//                          unmatched_frac  fraction of detections with no true object (of any
//                                        S/N) within 1.5 px: noise peaks and deblending debris
// Both also run SExtractor (`source-extractor`, else `sex`, from PATH) once on the same image,
// with share/data/sextractor/hdf.sex (the same parameters), and report
//   sextractor_s  its wall time (fork/exec, output to a temporary catalogue), and
//   ratio         sextractor_s / our wall time per iteration,
// plus sex_objects and sex_matched / sex_completeness / sex_median_err_px: the same error
// measures for its catalogue; on the HDF, sex_agree: the fraction of SExtractor's objects
// that have a detection of ours within 1 px. Without SExtractor those are NaN and the label
// says why (our timing is still reported). SExtractor's time includes reading the FITS files;
// ours starts from pixels in memory.
#include "shapesim/detect.hpp"
#include "shapesim/fits_io.hpp"
#include "../unit/test_support.hpp"

#include <benchmark/benchmark.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

extern char** environ;

using namespace shapesim;

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
constexpr double nan = std::numeric_limits<double>::quiet_NaN();

const std::string kSource = shapesim::test::source_dir();
const std::string kHdfImage = kSource + "/share/data/hdfn/hdfn_f814w_v2.fits";
const std::string kHdfWeight = kSource + "/share/data/hdfn/hdfn_f814w_v2_weight.fits";
const std::string kHdfCatalogue = kSource + "/share/data/hdfn/hdfn_f814w_v2.sextractor.cat";
const std::string kSexDir = kSource + "/share/data/sextractor";
constexpr double kZeroPoint = 22.08;

// ---------------------------------------------------------------------------------------------
// SExtractor ASCII_HEAD catalogues: "#   3 Y_IMAGE  comment [unit]" lines, then rows.

struct AsciiCatalogue {
    std::map<std::string, std::size_t> column;  // name → 0-based column
    std::vector<std::vector<double>> rows;

    std::size_t index(const std::string& name, const std::string& path) const {
        const auto it = column.find(name);
        if (it == column.end()) throw std::runtime_error(path + ": no column " + name);
        return it->second;
    }
};

AsciiCatalogue read_ascii_head(const std::string& path) {
    std::ifstream in(path);
    if (!in) throw std::runtime_error(path + ": cannot open");
    AsciiCatalogue cat;
    std::string line;
    while (std::getline(in, line)) {
        std::istringstream fields(line);
        if (!line.empty() && line[0] == '#') {
            std::string hash, name;
            std::size_t number = 0;
            if (fields >> hash >> number >> name && number > 0) cat.column[name] = number - 1;
            continue;
        }
        std::vector<double> row;
        for (double v; fields >> v;) row.push_back(v);
        if (row.empty()) continue;
        if (row.size() < cat.column.size())
            throw std::runtime_error(path + ": short row: " + line);
        cat.rows.push_back(std::move(row));
    }
    return cat;
}

// ---------------------------------------------------------------------------------------------
// Matching: for each point of `from`, the distance to the nearest point of `to` within
// `radius` (+∞ when none), through a grid of cells of side `radius`.

struct Point {
    double x = 0.0, y = 0.0;
};

std::vector<double> nearest_within(const std::vector<Point>& from, const std::vector<Point>& to,
                                   double radius) {
    const double infinity = std::numeric_limits<double>::infinity();
    std::map<std::pair<long, long>, std::vector<std::size_t>> cells;
    const auto cell = [radius](double v) { return long(std::floor(v / radius)); };
    for (std::size_t k = 0; k < to.size(); ++k)
        cells[{cell(to[k].x), cell(to[k].y)}].push_back(k);
    std::vector<double> distance(from.size(), infinity);
    for (std::size_t k = 0; k < from.size(); ++k) {
        const long cx = cell(from[k].x), cy = cell(from[k].y);
        for (long dy = -1; dy <= 1; ++dy)
            for (long dx = -1; dx <= 1; ++dx) {
                const auto it = cells.find({cx + dx, cy + dy});
                if (it == cells.end()) continue;
                for (std::size_t j : it->second) {
                    const double d = std::hypot(from[k].x - to[j].x, from[k].y - to[j].y);
                    if (d <= radius) distance[k] = std::min(distance[k], d);
                }
            }
    }
    return distance;
}

double matched_fraction(const std::vector<double>& distance) {
    if (distance.empty()) return nan;
    const auto n = std::count_if(distance.begin(), distance.end(),
                                 [](double d) { return std::isfinite(d); });
    return double(n) / double(distance.size());
}

double median_finite(std::vector<double> values) {
    values.erase(std::remove_if(values.begin(), values.end(),
                                [](double d) { return !std::isfinite(d); }),
                 values.end());
    if (values.empty()) return nan;
    const auto mid = values.begin() + std::ptrdiff_t(values.size() / 2);
    std::nth_element(values.begin(), mid, values.end());
    return *mid;
}

std::vector<Point> positions(const std::vector<Detection>& objects) {
    std::vector<Point> p;
    p.reserve(objects.size());
    for (const Detection& d : objects) p.push_back({d.x, d.y});
    return p;
}

std::vector<Point> positions(const AsciiCatalogue& cat, const std::string& path) {
    const std::size_t ix = cat.index("X_IMAGE", path), iy = cat.index("Y_IMAGE", path);
    std::vector<Point> p;
    for (const auto& row : cat.rows) p.push_back({row[ix], row[iy]});
    return p;
}

// ---------------------------------------------------------------------------------------------
// Running SExtractor once: found on PATH, fork/exec'd (posix_spawn) with stdin and stdout on
// /dev/null and stderr to a file (quoted when it fails), timed on the wall clock.

std::string find_on_path(const std::string& name) {
    const char* path = std::getenv("PATH");
    std::istringstream dirs(path ? path : "/usr/bin:/bin");
    for (std::string dir; std::getline(dirs, dir, ':');) {
        const std::string candidate = (dir.empty() ? "." : dir) + "/" + name;
        if (::access(candidate.c_str(), X_OK) == 0 && !fs::is_directory(candidate))
            return candidate;
    }
    return {};
}

std::string sextractor_program() {
    for (const char* name : {"source-extractor", "sex"})
        if (std::string found = find_on_path(name); !found.empty()) return found;
    return {};
}

// A private scratch folder, removed with its contents when the object goes.
class TempDir {
public:
    TempDir() {
        const char* base = std::getenv("TMPDIR");
        std::string pattern = std::string(base && *base ? base : "/tmp") + "/detect_bench.XXXXXX";
        if (!::mkdtemp(pattern.data())) throw std::runtime_error("mkdtemp " + pattern + " failed");
        path_ = pattern;
    }
    ~TempDir() {
        std::error_code ignored;
        fs::remove_all(path_, ignored);
    }
    TempDir(const TempDir&) = delete;
    TempDir& operator=(const TempDir&) = delete;
    const std::string& path() const { return path_; }

private:
    std::string path_;
};

struct SexRun {
    double seconds = nan;
    std::string error;  // empty when it ran and its catalogue was read
    AsciiCatalogue catalogue;
    std::string catalogue_path;
};

// `extra`: options after the shared ones (later options win in SExtractor).
SexRun run_sextractor(const std::string& image, const std::string& weight,
                      const std::vector<std::string>& extra, const TempDir& dir) {
    SexRun run;
    const std::string program = sextractor_program();
    if (program.empty()) {
        run.error = "source-extractor not on PATH: no SExtractor timing";
        return run;
    }
    run.catalogue_path = dir.path() + "/sextractor.cat";
    const std::string log = dir.path() + "/sextractor.log";
    std::vector<std::string> args = {program,         image,
                                     "-c",            kSexDir + "/hdf.sex",
                                     "-PARAMETERS_NAME", kSexDir + "/hdf.param",
                                     "-FILTER_NAME",  kSexDir + "/default.conv",
                                     "-WEIGHT_IMAGE", weight,
                                     "-CATALOG_NAME", run.catalogue_path,
                                     "-VERBOSE_TYPE", "QUIET"};
    // hdf.sex names Debian's network; elsewhere use the first one found.
    for (const char* nnw : {"/usr/share/source-extractor/default.nnw",
                            "/usr/share/sextractor/default.nnw",
                            "/usr/local/share/sextractor/default.nnw"})
        if (fs::exists(nnw)) {
            args.insert(args.end(), {"-STARNNW_NAME", nnw});
            break;
        }
    args.insert(args.end(), extra.begin(), extra.end());
    std::vector<char*> argv;
    for (std::string& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);

    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0);
    posix_spawn_file_actions_addopen(&actions, 1, "/dev/null", O_WRONLY, 0);
    posix_spawn_file_actions_addopen(&actions, 2, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC,
                                     0644);
    pid_t pid = 0;
    const auto start = Clock::now();
    const int spawned = posix_spawn(&pid, program.c_str(), &actions, nullptr, argv.data(), environ);
    int status = 0;
    if (spawned == 0)
        while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
        }
    const double seconds = std::chrono::duration<double>(Clock::now() - start).count();
    posix_spawn_file_actions_destroy(&actions);
    if (spawned != 0) {
        run.error = program + ": cannot run (errno " + std::to_string(spawned) + ")";
        return run;
    }
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
        std::ifstream in(log);
        std::string text, line;
        while (std::getline(in, line))
            if (!line.empty()) text = line;
        run.error = program + " failed (status " + std::to_string(status) + "): " + text;
        return run;
    }
    try {
        run.catalogue = read_ascii_head(run.catalogue_path);
    } catch (const std::exception& e) {
        run.error = e.what();
        return run;
    }
    run.seconds = seconds;
    return run;
}

// Our wall time per iteration, for the ratio.
struct Stopwatch {
    double total = 0.0;
    Clock::time_point start;
    void begin() { start = Clock::now(); }
    void end() { total += std::chrono::duration<double>(Clock::now() - start).count(); }
};

void report_sextractor(benchmark::State& state, const SexRun& sex, double our_seconds) {
    state.counters["sextractor_s"] = sex.seconds;
    state.counters["ratio"] = sex.seconds / our_seconds;
    state.counters["sex_objects"] = sex.error.empty() ? double(sex.catalogue.rows.size()) : nan;
    if (!sex.error.empty()) state.SetLabel(sex.error);
}

// ---------------------------------------------------------------------------------------------
// The HDF-N cut.

struct HdfData {
    ImageArray image, inverse_variance;
    std::vector<Point> bright;  // shipped catalogue, MAG_BEST + 22.08 < 28, x corrected
    SexRun sex;                 // SExtractor on the same files, same settings
};

const HdfData& hdf_data() {
    static const HdfData data = [] {
        HdfData d;
        d.image = read_fits_image(kHdfImage);
        d.inverse_variance =
            inverse_variance_from(read_fits_image(kHdfWeight), NoiseMapType::weight, kHdfWeight);
        const AsciiCatalogue cat = read_ascii_head(kHdfCatalogue);
        const std::size_t ix = cat.index("X_IMAGE", kHdfCatalogue),
                          iy = cat.index("Y_IMAGE", kHdfCatalogue),
                          im = cat.index("MAG_BEST", kHdfCatalogue);
        for (const auto& row : cat.rows)
            if (row[im] + kZeroPoint < 28.0) d.bright.push_back({row[ix] - 1.0, row[iy]});
        TempDir dir;
        d.sex = run_sextractor(kHdfImage, kHdfWeight, {}, dir);
        return d;
    }();
    return data;
}

void BM_DetectHdf(benchmark::State& state) {
    try {
        const HdfData& data = hdf_data();
        const DetectionOptions options;
        DetectionResult result;
        Stopwatch ours;
        for (auto _ : state) {
            ours.begin();
            result = detect_sources(data.image, &data.inverse_variance, options);
            ours.end();
            benchmark::DoNotOptimize(result.objects.data());
        }
        const std::vector<Point> found = positions(result.objects);
        state.counters["objects"] = double(result.objects.size());
        state.counters["cat_objects"] = double(data.bright.size());
        state.counters["cat_matched"] = matched_fraction(nearest_within(data.bright, found, 1.0));
        if (data.sex.error.empty()) {
            const std::vector<Point> sex = positions(data.sex.catalogue, data.sex.catalogue_path);
            state.counters["sex_matched"] = matched_fraction(nearest_within(data.bright, sex, 1.0));
            state.counters["sex_agree"] = matched_fraction(nearest_within(sex, found, 1.0));
        }
        report_sextractor(state, data.sex, ours.total / double(state.iterations()));
    } catch (const std::exception& e) {
        state.SkipWithError(e.what());
    }
}
BENCHMARK(BM_DetectHdf)->Unit(benchmark::kMillisecond)->UseRealTime();

// ---------------------------------------------------------------------------------------------
// A synthetic field of known objects.

constexpr double kNoise = 1.0, kPsfSigma = 1.5, kMinSnr = 10.0, kMatchRadius = 1.5;

struct SyntheticData {
    test::SyntheticField field;
    std::vector<Point> truth, bright;  // all true objects; those with S/N > kMinSnr
    SexRun sex;
};

// Optimal (matched-filter) S/N of a Gaussian of σ s and total flux F in white noise σ_n:
// F / (σ_n √(4π) s).
double optimal_snr(const test::SyntheticObject& o) {
    constexpr double pi = 3.14159265358979323846;
    return o.flux / (kNoise * std::sqrt(4.0 * pi) * o.sigma);
}

const SyntheticData& synthetic_data(int size) {
    static std::map<int, std::unique_ptr<SyntheticData>> cache;
    auto& slot = cache[size];
    if (slot) return *slot;
    auto d = std::make_unique<SyntheticData>();
    // 40 px spacing: ~10⁴ objects in 4096², fluxes giving S/N ≈ 1.5–250, every 7th a star.
    d->field = test::synthetic_field(size, size, 40.0, 20.0, 4000.0, kNoise, 2024, kPsfSigma, 7);
    for (const test::SyntheticObject& o : d->field.objects) {
        d->truth.push_back({o.x, o.y});
        if (optimal_snr(o) > kMinSnr) d->bright.push_back({o.x, o.y});
    }
    // SExtractor reads the same pixels from float32 files (FitsWriter: extension 1).
    TempDir dir;
    const std::string image = dir.path() + "/synthetic.fits";
    const std::string weight = dir.path() + "/synthetic_weight.fits";
    for (const auto& [path, pixels] : {std::pair{image, &d->field.image},
                                       std::pair{weight, &d->field.weight}}) {
        FitsWriter out(path, "detect_bench");
        out.write_image(*pixels, FitsImageSpec{"SCI", -32, {}, std::nullopt, {}, {}});
        out.commit();
    }
    // No WCS: pixel units; the PSF FWHM for CLASS_STAR in pixels.
    const double fwhm = 2.0 * std::sqrt(2.0 * std::log(2.0)) * kPsfSigma;
    d->sex = run_sextractor(image, weight,
                            {"-PIXEL_SCALE", "1", "-SEEING_FWHM", std::to_string(fwhm)}, dir);
    slot = std::move(d);
    return *slot;
}

void BM_DetectSynthetic(benchmark::State& state) {
    try {
        const SyntheticData& data = synthetic_data(int(state.range(0)));
        const DetectionOptions options;
        DetectionResult result;
        Stopwatch ours;
        for (auto _ : state) {
            ours.begin();
            result = detect_sources(data.field.image, &data.field.weight, options);
            ours.end();
            benchmark::DoNotOptimize(result.objects.data());
        }
        const std::vector<Point> found = positions(result.objects);
        const std::vector<double> bright = nearest_within(data.bright, found, kMatchRadius);
        state.counters["objects"] = double(result.objects.size());
        state.counters["true_objects"] = double(data.truth.size());
        state.counters["completeness"] = matched_fraction(bright);
        state.counters["median_err_px"] = median_finite(bright);
        state.counters["unmatched_frac"] =
            1.0 - matched_fraction(nearest_within(found, data.truth, kMatchRadius));
        if (data.sex.error.empty()) {
            const std::vector<double> sex_bright = nearest_within(
                data.bright, positions(data.sex.catalogue, data.sex.catalogue_path),
                kMatchRadius);
            state.counters["sex_completeness"] = matched_fraction(sex_bright);
            state.counters["sex_median_err_px"] = median_finite(sex_bright);
        }
        report_sextractor(state, data.sex, ours.total / double(state.iterations()));
    } catch (const std::exception& e) {
        state.SkipWithError(e.what());
    }
}
// A few seconds per detection: a fixed, small iteration count keeps the run short.
BENCHMARK(BM_DetectSynthetic)->Arg(4096)->Iterations(2)->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace
