// shapesim-survey: one survey description (`name = value` lines) → shapesim-sample →
// shapesim-render: an image of the telescope's field, its objects and its truth, in one
// command. The programs do the work; this one turns the survey's physical units (zero point
// of 1 e-/s, exposure, gain, read noise, sky in mag/arcsec^2) into their options, finds the
// installed models, runs the two programs beside it, and writes the commands it ran.
#include "shapesim/analytic_psf.hpp"
#include "app/field_options.hpp"
#include "app/log.hpp"
#include "app/options.hpp"
#include "app/run_main.hpp"
#include "shapesim/atomic_file.hpp"
#include "shapesim/error.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

extern char** environ;

namespace {

using namespace shapesim;
namespace po = app::po;
namespace fs = std::filesystem;

const char* const description =
    "Simulate a survey described in one file of `name = value` lines (the options below):\n"
    "the telescope's pixel scale and field, its PSF (analytic or a PSF record), zero point,\n"
    "exposure, gain, read noise and sky, the depth, the shear. Runs shapesim-sample,\n"
    "shapesim-render and shapesim-table (found beside this program) into the directory -o:\n"
    "image.fits (in electron/s, or adu with units = adu; EXPTIME, GAIN, BUNIT, MAGZERO, WCS\n"
    "in the header), objects.jsonl (what was drawn), truth.jsonl and truth.fits (what is in\n"
    "the image; the FITS table has units) and commands.sh (the commands, to rerun or change\n"
    "by hand). Options on the command line win over the file's. Shipped surveys (acs-f814w,\n"
    "euclid-vis, rubin-i, hdf) are found by name.\n"
    "\n"
    "Examples:\n"
    "  shapesim-survey rubin-i -o rubin/\n"
    "  shapesim-survey acs-f814w --shear 0.02 0 --seed 3 -o cosmos-sheared/\n"
    "  shapesim-survey my.survey --dry-run      # print the two commands only";

struct Settings {
    std::string model = "merged", galaxy_psf, psf, units = "e/s";
    double zero_point = 0.0, exposure = 0.0, gain = 1.0, read_noise = 0.0, sky = 0.0,
           sky_electrons = 0.0, mag_limit = 0.0, faint_limit = 0.0, kappa = 0.0,
           star_density = 0.0, star_mag_min = 0.0, star_mag_max = 0.0, full_well = 0.0;
    std::vector<double> shear;
    app::FieldOptions field;
    bool dry_run = false, noise_free = false;
};

// Where the shipped data lives: $SHAPESIM_DATA, else beside the program: an installed prefix
// (bin/../share/shapesim) or a build tree (bin/../share/data).
fs::path data_dir() {
    if (const char* env = std::getenv("SHAPESIM_DATA"); env && *env) return env;
    std::error_code ec;
    const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
    if (ec) return {};
    for (const fs::path& p : {exe.parent_path() / ".." / "share" / "shapesim",
                              exe.parent_path() / ".." / "share" / "data"})
        if (fs::is_directory(p / "models", ec)) return fs::weakly_canonical(p, ec);
    return {};
}

// A file named in the survey: as given (relative to the working directory), else relative to
// the survey file, else the shipped `folder/name` + `extension` (a name like "merged").
std::string find_file(const std::string& name, const fs::path& survey_dir, const fs::path& data,
                      const std::string& folder, const std::string& extension,
                      const std::string& what) {
    std::error_code ec;
    if (fs::is_regular_file(name, ec)) return name;
    if (!survey_dir.empty() && fs::path(name).is_relative() &&
        fs::is_regular_file(survey_dir / name, ec))
        return (survey_dir / name).string();
    if (!data.empty()) {
        for (const fs::path& p : {data / folder / name, data / folder / (name + extension)})
            if (fs::is_regular_file(p, ec)) return p.string();
    }
    std::vector<std::string> names;
    if (!data.empty() && fs::is_directory(data / folder, ec))
        for (const auto& entry : fs::directory_iterator(data / folder, ec)) {
            const std::string file = entry.path().filename().string();
            if (file.size() > extension.size() &&
                file.compare(file.size() - extension.size(), extension.size(), extension) == 0 &&
                file.find('.') == file.size() - extension.size())
                names.push_back(file.substr(0, file.size() - extension.size()));
        }
    std::sort(names.begin(), names.end());
    std::string shipped;
    for (const std::string& n : names) shipped += (shipped.empty() ? "" : ", ") + n;
    throw po::error(what + " '" + name + "': no such file" +
                    (shipped.empty() ? std::string(" (no shipped data found)")
                                     : " and not a shipped one (" + shipped + ")"));
}

std::string quoted(const std::string& word) {
    if (!word.empty() &&
        word.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ"
                               "0123456789-_./:,=+@%") == std::string::npos)
        return word;
    std::string q = "'";
    for (char c : word) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return q + "'";
}

std::string command_line(const std::vector<std::string>& argv) {
    std::string line;
    for (const std::string& a : argv) line += (line.empty() ? "" : " ") + quoted(a);
    return line;
}

// Run argv (its program given by path) and wait; Error unless it exits 0. Its stderr is ours.
void run(const std::vector<std::string>& argv) {
    std::vector<char*> args;
    for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    pid_t pid = 0;
    if (const int e = posix_spawn(&pid, args[0], nullptr, nullptr, args.data(), environ); e != 0)
        throw Error(std::string("cannot run: ") + std::strerror(e), argv[0]);
    int status = 0;
    while (waitpid(pid, &status, 0) < 0)
        if (errno != EINTR) throw Error(std::string("waitpid: ") + std::strerror(errno), argv[0]);
    if (WIFSIGNALED(status))
        throw Error("killed by signal " + std::to_string(WTERMSIG(status)), argv[0]);
    if (WEXITSTATUS(status) != 0)
        throw Error("failed (exit " + std::to_string(WEXITSTATUS(status)) + ", its message above)",
                    argv[0]);
}

// A shipped survey given by name (`shapesim-survey rubin-i`): the argument that names no file
// but a shipped data/surveys/NAME.survey becomes that file's path.
std::vector<std::string> with_shipped_surveys(int argc, const char* const argv[]) {
    std::vector<std::string> args(argv, argv + argc);
    const fs::path data = data_dir();
    std::error_code ec;
    for (std::size_t k = 1; k < args.size() && !data.empty(); ++k) {
        const std::string& a = args[k];
        if (a.empty() || a[0] == '-' || a.find('/') != std::string::npos || fs::exists(a, ec))
            continue;
        const fs::path shipped = data / "surveys" / (a + ".survey");
        if (fs::is_regular_file(shipped, ec)) args[k] = shipped.string();
    }
    return args;
}

int run_survey(int argc_given, const char* const argv_given[]) {
    const std::vector<std::string> args = with_shipped_surveys(argc_given, argv_given);
    std::vector<const char*> arg_pointers;
    for (const std::string& a : args) arg_pointers.push_back(a.c_str());
    const int argc = int(arg_pointers.size());
    const char* const* argv = arg_pointers.data();
    app::ProgramOptions options("shapesim-survey", "[OPTION]... SURVEY -o DIR", description,
                                app::Common::output | app::Common::quiet | app::Common::verbose |
                                    app::Common::threads | app::Common::seed |
                                    app::Common::config | app::Common::print_params);
    Settings s;
    using app::in_range;
    options.group("Model").add_options()
        ("model", po::value(&s.model)->value_name("NAME|FILE")->default_value("merged"),
         "the morphology model drawn from: a shapesim-smooth output, or a shipped one: "
         "'merged' (intrinsic: HDF-N, XDF, COSMOS/AEGIS; for any PSF) or 'hdf' (the HDF-N "
         "as observed through WFPC2)")
        ("galaxy-psf", po::value(&s.galaxy_psf)->value_name("FILE"),
         "the PSF an observed-frame model's galaxies already hold (default: the model's "
         "NAME.psf.jsonl beside it)");
    s.field.declare(options, "Field", "render only these field pixels (FITS, inclusive)");
    options.group("Telescope").add_options()
        ("psf", po::value(&s.psf)->value_name("SPEC|FILE"),
         "the PSF: gaussian:FWHM, moffat:FWHM[,BETA], airy:LAMBDA_OVER_D[,OBSCURATION] "
         "(arcsec; ;jitter=SIGMA) or a PSF record (shapesim-decompose --psf-image)")
        ("zero-point", po::value(&s.zero_point)->notifier(in_range("zero-point", -100.0, 100.0)),
         "AB magnitude of 1 electron/s (required)")
        ("exposure", po::value(&s.exposure)->notifier(in_range("exposure", 1e-6, 1e9)),
         "exposure time, seconds (required)")
        ("gain", po::value(&s.gain)->default_value(1.0)->notifier(in_range("gain", 1e-6, 1e6)),
         "electrons per ADU (units = adu)")
        ("read-noise", po::value(&s.read_noise)->default_value(0.0)
             ->notifier(in_range("read-noise", 0.0, 1e6)),
         "read noise, electrons rms per pixel (all reads of the exposure)")
        ("full-well", po::value(&s.full_well)->value_name("ELECTRONS")
             ->notifier(in_range("full-well", 0.0, 1e15)),
         "a pixel's full well, electrons (sky included): brighter pixels saturate at it "
         "(SATURATE in the header, in image units); 0: none")
        ("sky", po::value(&s.sky)->value_name("MAG_ARCSEC2")
             ->notifier(in_range("sky", -100.0, 100.0)),
         "sky brightness, AB mag/arcsec^2 (its photon noise is drawn)")
        ("sky-electrons", po::value(&s.sky_electrons)
             ->notifier(in_range("sky-electrons", 0.0, 1e15)),
         "sky, electrons per pixel over the exposure, instead of --sky")
        ("units", po::value(&s.units)->default_value("e/s"),
         "image units: e/s (electron/s, as HST's drizzled images) or adu (counts over the "
         "exposure / gain)");
    options.group("Sky").add_options()
        ("mag-limit", po::value(&s.mag_limit)->notifier(in_range("mag-limit", -100.0, 100.0)),
         "faintest galaxy drawn, AB (default: shapesim-sample's)")
        ("faint-limit", po::value(&s.faint_limit)->notifier(in_range("faint-limit", -100.0, 100.0)),
         "also the unresolved galaxies down to this magnitude (shapesim-sample --faint-limit)")
        ("star-density", po::value(&s.star_density)->notifier(in_range("star-density", 0.0, 1e8)),
         "stars per arcmin^2")
        ("star-mag-min", po::value(&s.star_mag_min)
             ->notifier(in_range("star-mag-min", -100.0, 100.0)),
         "brightest star, AB")
        ("star-mag-max", po::value(&s.star_mag_max)
             ->notifier(in_range("star-mag-max", -100.0, 100.0)),
         "faintest star, AB")
        ("shear", po::value(&s.shear)->value_name("G1 G2")->multitoken(),
         "reduced shear applied to every galaxy")
        ("kappa", po::value(&s.kappa)->notifier(in_range("kappa", -1.0, 1.0)), "convergence");
    options.group("Run").add_options()
        ("dry-run", po::bool_switch(&s.dry_run), "print the two commands and exit")
        ("noise-free", po::bool_switch(&s.noise_free), "no noise (truth images)");
    options.positional("config", 1);
    if (!options.parse(argc, argv)) return 0;
    const app::Log log("shapesim-survey", options.common().verbosity);

    const std::string& config = options.common().config;
    if (config.empty()) throw po::error("give the survey file (or --config FILE)");
    if (!options.given("zero-point"))
        throw po::error("the survey needs zero-point (AB mag of 1 e-/s)");
    if (!options.given("exposure")) throw po::error("the survey needs exposure (seconds)");
    if (!options.given("psf"))
        throw po::error("the survey needs psf (an analytic SPEC or a record)");
    if (options.given("sky") && options.given("sky-electrons"))
        throw po::error("give sky (mag/arcsec^2) or sky-electrons, not both");
    if (s.units != "e/s" && s.units != "adu") throw po::error("--units: e/s or adu");
    if (!s.shear.empty() && s.shear.size() != 2)
        throw po::error("--shear takes two numbers: G1 G2");
    const std::string& out = options.common().output;
    if (out.empty() && !s.dry_run) throw po::error("give the output directory: -o DIR");

    const fs::path data = data_dir();
    const fs::path survey_dir = fs::path(config).parent_path();
    const std::string model = find_file(s.model, survey_dir, data, "models", ".json", "model");
    // The model's frame decides the galaxy kernel: observed-frame galaxies hold a PSF already.
    std::string frame;
    {
        std::ifstream in(model);
        std::string line;
        std::getline(in, line);
        const nlohmann::json j = nlohmann::json::parse(line, nullptr, false);
        if (j.is_discarded() || !j.is_object())
            throw Error("not a morphology model (one JSON document on its first line)", model);
        frame = j.value("frame", std::string("observed"));
    }
    std::string galaxy_psf = s.galaxy_psf;
    if (galaxy_psf.empty() && frame == "observed") {
        fs::path beside = fs::path(model);
        beside.replace_extension(".psf.jsonl");
        std::error_code ec;
        if (!fs::is_regular_file(beside, ec))
            throw po::error("the model " + model + " is of observed galaxies (their PSF "
                            "included): give galaxy-psf, the PSF they were observed through");
        galaxy_psf = beside.string();
    } else if (!galaxy_psf.empty()) {
        galaxy_psf = find_file(galaxy_psf, survey_dir, data, "models", ".psf.jsonl", "galaxy-psf");
    }
    bool analytic = false;
    try {
        parse_analytic_psf(s.psf);
        analytic = true;
    } catch (const Error&) {
    }
    const std::string psf =
        analytic ? s.psf : find_file(s.psf, survey_dir, data, "psfs", ".jsonl", "psf");

    // Units. e/s: one image unit is 1 e-/s, the zero point is the survey's, photon noise
    // counts unit × exposure electrons. adu: one unit is `gain` electrons over the exposure.
    const double T = s.exposure, p = s.field.pixel_scale;
    const bool adu = s.units == "adu";
    const double zp_image = adu ? s.zero_point + 2.5 * std::log10(T / s.gain) : s.zero_point;
    const double sky_electrons =
        options.given("sky") ? std::pow(10.0, -0.4 * (s.sky - s.zero_point)) * p * p * T
                             : s.sky_electrons;
    const double electrons_per_unit = adu ? s.gain : T;
    const double sky_image = sky_electrons / electrons_per_unit;
    const double read_image = s.read_noise / electrons_per_unit;

    const fs::path dir = out.empty() ? fs::path(".") : fs::path(out);
    const fs::path bin = fs::read_symlink("/proc/self/exe").parent_path();
    const std::string seed = std::to_string(options.common().seed);
    std::vector<std::string> field;
    if (options.given("pixels")) {
        field = {"--pixels"};
        for (long n : s.field.pixels) field.push_back(std::to_string(n));
    } else if (options.given("area")) {
        field = {"--area", app::double_text(s.field.area)};
    } else if (options.given("size")) {
        field = {"--size"};
        for (double v : s.field.size) field.push_back(app::double_text(v));
    } else {
        throw po::error("the survey needs its field: pixels, area or size");
    }
    for (const std::string& o : std::vector<std::string>{"pixel-scale", "ra", "dec"}) {
        field.push_back("--" + o);
        field.push_back(app::double_text(o == "pixel-scale" ? s.field.pixel_scale
                               : o == "ra"        ? s.field.ra
                                                  : s.field.dec));
    }
    std::vector<std::string> tile;
    if (options.given("tile")) {
        tile = {"--tile"};
        for (double v : s.field.tile) tile.push_back(app::double_text(v));
    }
    const std::string objects = (dir / "objects.jsonl").string();
    std::vector<std::string> sample = {(bin / "shapesim-sample").string(), model};
    sample.insert(sample.end(), field.begin(), field.end());
    sample.insert(sample.end(), {"--zero-point", app::double_text(zp_image), "--seed", seed});
    if (options.given("mag-limit"))
        sample.insert(sample.end(), {"--mag-limit", app::double_text(s.mag_limit)});
    if (options.given("faint-limit"))
        sample.insert(sample.end(), {"--faint-limit", app::double_text(s.faint_limit)});
    if (options.given("star-density"))
        sample.insert(sample.end(), {"--star-density", app::double_text(s.star_density)});
    if (options.given("star-mag-min"))
        sample.insert(sample.end(), {"--star-mag-min", app::double_text(s.star_mag_min)});
    if (options.given("star-mag-max"))
        sample.insert(sample.end(), {"--star-mag-max", app::double_text(s.star_mag_max)});
    sample.insert(sample.end(), tile.begin(), tile.end());
    if (options.common().verbosity == app::Verbosity::quiet) sample.push_back("-q");
    sample.insert(sample.end(), {"-o", objects});

    std::vector<std::string> render = {(bin / "shapesim-render").string(), objects};
    render.insert(render.end(), {analytic ? "--psf-analytic" : "--psf", psf});
    if (!galaxy_psf.empty()) render.insert(render.end(), {"--galaxy-psf", galaxy_psf});
    render.insert(render.end(), field.begin(), field.end());
    render.insert(render.end(), tile.begin(), tile.end());
    if (s.noise_free) {
        render.push_back("--noise-free");
    } else {
        render.insert(render.end(), {"--noise-rms", app::double_text(read_image), "--gain",
                                     app::double_text(adu ? s.gain : 1.0)});
        if (s.full_well > 0.0)
            render.insert(render.end(),
                          {"--saturation", app::double_text(s.full_well / electrons_per_unit)});
    }
    render.insert(render.end(), {adu ? "--exptime" : "--exposure", app::double_text(T)});
    render.insert(render.end(),
                  {"--sky", app::double_text(sky_image), "--bunit", adu ? "adu" : "electron/s"});
    if (!s.shear.empty())
        render.insert(render.end(),
                      {"--shear", app::double_text(s.shear[0]), app::double_text(s.shear[1])});
    if (options.given("kappa")) render.insert(render.end(), {"--kappa", app::double_text(s.kappa)});
    render.insert(render.end(), {"--seed", seed, "-j", std::to_string(options.common().threads)});
    if (options.common().verbosity == app::Verbosity::quiet) render.push_back("-q");
    render.insert(render.end(), {"-o", (dir / "image.fits").string(), "--truth",
                                 (dir / "truth.jsonl").string()});
    // The truth as a FITS binary table with units, for astropy, TOPCAT and fv.
    const std::vector<std::string> table = {(bin / "shapesim-table").string(),
                                            (dir / "truth.jsonl").string(), "--like",
                                            (dir / "image.fits").string(), "-o",
                                            (dir / "truth.fits").string()};
    if (s.dry_run) {
        std::cout << command_line(sample) << '\n' << command_line(render) << '\n'
                  << command_line(table) << '\n';
        return 0;
    }
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (ec) throw Error("cannot make the directory: " + ec.message(), dir.string());
    AtomicTextFile commands((dir / "commands.sh").string());
    commands.stream() << "#!/bin/sh\n# shapesim-survey " << config
                      << ": the commands it ran\nset -e\n"
                      << command_line(sample) << '\n'
                      << command_line(render) << '\n'
                      << command_line(table) << '\n';
    log.info("sky ", sky_electrons, " e-/pixel, read noise ", s.read_noise, " e-; image unit ",
             adu ? "adu" : "electron/s", ", zero point ", zp_image);
    log.verbose(command_line(sample));
    run(sample);
    log.verbose(command_line(render));
    run(render);
    log.verbose(command_line(table));
    run(table);
    commands.commit();
    log.info("wrote ", (dir / "image.fits").string(), ", ", objects, ", ",
             (dir / "truth.jsonl").string(), " and ", (dir / "truth.fits").string());
    return 0;
}

}  // namespace

int main(int argc, char** argv) { return app::run_main(argc, argv, "shapesim-survey", run_survey); }
