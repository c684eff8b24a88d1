// shapesim-calibrate: truth catalogues (shapesim-render --truth) and the shape catalogues
// measured on their images → the shear calibration e = (1 + m) g + c, overall and in bins, as
// a Markdown report (and JSON). The work is in the library: calibration.hpp, table.hpp.
#include "app/gnuplot.hpp"
#include "app/options.hpp"
#include "app/run_main.hpp"
#include "shapesim/atomic_file.hpp"
#include "shapesim/calibration.hpp"
#include "shapesim/constants.hpp"
#include "shapesim/error.hpp"
#include "shapesim/geometry.hpp"
#include "shapesim/jsonl.hpp"
#include "shapesim/records.hpp"
#include "shapesim/rng.hpp"
#include "shapesim/table.hpp"

#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <map>
#include <optional>
#include <sstream>

namespace {

// The truth's fields a --bin may name (besides the shape catalogue's columns).
const std::vector<std::string> truth_bin_fields = {"mag",   "flux",   "rms_radius", "kappa",
                                                   "mu",    "psf_e1", "psf_e2",
                                                   "psf_rms_radius"};
std::string truth_bin_list() {
    std::string list;
    for (const std::string& f : truth_bin_fields) list += (list.empty() ? "" : ", ") + f;
    return list;
}

using namespace shapesim;
namespace po = app::po;

const char* const description =
    "Match each shape catalogue to the truth of the image it was measured on and fit the\n"
    "shear response e = (1 + m) g + c per component: m the multiplicative bias, c the additive\n"
    "one, with bootstrap errors (a ring of rotated copies resampled whole), overall and in\n"
    "bins of any column (magnitude, size, S/N). Any catalogue a user has: JSON lines\n"
    "(shapesim-measure's, or a user's), CSV with a header, SExtractor's ASCII_HEAD or a FITS\n"
    "table (FITS_LDAC too), positions in the image's pixels (or --sky ra, dec). The truth's g\n"
    "needs to vary: a shear field (shapesim-lens) or several images with different shears.\n"
    "Writes a Markdown report (stdout, or -o) and, with --json, the numbers.\n"
    "\n"
    "Examples:\n"
    "  shapesim-calibrate truth.jsonl shapes.jsonl > calibration.md\n"
    "  shapesim-calibrate --position XWIN_IMAGE,YWIN_IMAGE --bin SNR_WIN:4 \\\n"
    "      --moments X2WIN_IMAGE,Y2WIN_IMAGE,XYWIN_IMAGE truth.jsonl sex.cat   # SExtractor's\n"
    "  shapesim-calibrate t1.jsonl s1.csv t2.jsonl s2.csv --json m_c.json   # two images";

struct Settings {
    std::vector<std::string> files, bins;
    std::string e1 = "e1", e2 = "e2", position = "x,y", moments, json, figures;
    double radius = 0.0, responsivity = 1.0;
    int bootstrap = 200;
    bool sky = false, flip_e2 = false, complete_rings = false;
};

struct Bin {
    std::string name;
    int count = 4;
};

std::pair<std::string, std::string> split_pair(const std::string& text, const char* option) {
    const auto comma = text.find(',');
    if (comma == std::string::npos || comma == 0 || comma + 1 == text.size() ||
        text.find(',', comma + 1) != std::string::npos)
        throw po::error(std::string("--") + option + ": give two names, NAME1,NAME2");
    return {text.substr(0, comma), text.substr(comma + 1)};
}

Bin parse_bin(const std::string& text) {
    Bin b;
    const auto colon = text.find(':');
    b.name = text.substr(0, colon);
    if (b.name.empty()) throw po::error("--bin: give a column name, NAME[:N]");
    if (colon != std::string::npos) {
        try {
            std::size_t used = 0;
            b.count = std::stoi(text.substr(colon + 1), &used);
            if (used != text.size() - colon - 1) throw std::invalid_argument("");
        } catch (const std::exception&) {
            throw po::error("--bin " + text + ": N must be a whole number");
        }
        if (b.count < 1 || b.count > 100) throw po::error("--bin " + text + ": N must be 1 to 100");
    }
    return b;
}

// One true galaxy: where, its shear, its block, the fields a bin may use.
struct TrueGalaxy {
    double x = 0.0, y = 0.0;
    double g1 = 0.0, g2 = 0.0;
    std::uint64_t block = 0;
    long ring_size = 1;  ///< the copies of its ring (1: none)
    std::map<std::string, double> fields;
};

std::vector<TrueGalaxy> read_truth(const std::string& path, std::size_t image, bool sky,
                                   std::optional<Wcs>& plane) {
    JsonlReader reader(path, {TruthRecord::schema});
    std::vector<TrueGalaxy> out;
    TruthRecord t;
    while (reader.next_record(t)) {
        if (t.kind != "galaxy" || !t.shape) continue;
        TrueGalaxy g;
        if (sky) {
            // The sky on a tangent plane of 1″ pixels about the first galaxy (across RA 0 too).
            if (!plane) plane = tan_wcs(t.ra, t.dec, 1.0, 0.0, 0.0);
            const PixelPosition p = plane->sky_to_pixel(t.ra, t.dec);
            g.x = p.x;
            g.y = p.y;
        } else {
            g.x = t.x;
            g.y = t.y;
        }
        g.g1 = t.shape->g1;
        g.g2 = t.shape->g2;
        // A ring's members are one bootstrap block; else the galaxy is.
        std::string block = std::to_string(image) + ":" + t.id;
        if (const auto ring = t.extra.find("ring"); ring != t.extra.end() && ring->is_object() &&
                                                    ring->contains("first") &&
                                                    (*ring)["first"].is_string()) {
            block = std::to_string(image) + ":ring:" + (*ring)["first"].get<std::string>();
            if (ring->contains("of") && (*ring)["of"].is_number_integer())
                g.ring_size = std::max<long>(1, (*ring)["of"].get<long>());
        }
        g.block = fnv1a_64(block);
        if (t.mag) g.fields["mag"] = *t.mag;
        g.fields["flux"] = t.flux;
        if (t.shape->rms_radius) g.fields["rms_radius"] = *t.shape->rms_radius;
        g.fields["kappa"] = t.shape->kappa;
        g.fields["mu"] = t.shape->mu;
        // The PSF where it was drawn, when the PSF varies (render --psf-field).
        for (const char* name : {"psf_e1", "psf_e2", "psf_rms_radius"})
            if (const auto v = t.extra.find(name); v != t.extra.end() && v->is_number())
                g.fields[name] = v->get<double>();
        out.push_back(std::move(g));
    }
    return out;
}

std::string cell(double v, double err) {
    char text[64];
    if (err > 0.0) std::snprintf(text, sizeof text, "%.3g ± %.2g", v, err);
    else std::snprintf(text, sizeof text, "%.3g", v);
    return text;
}

Json fit_json(const ShearCalibration& c) {
    auto component = [](const ComponentFit& f) {
        return Json{{"m", f.m}, {"m_err", f.m_err}, {"c", f.c}, {"c_err", f.c_err}};
    };
    return Json{{"galaxies", c.galaxies},
                {"blocks", c.blocks},
                {"g1", component(c.one)},
                {"g2", component(c.two)}};
}

// The figure: <e − g> in ten equal-count bins of g per component (mean and its error) with
// the fitted m g + c, and m1, m2 in the bins of `bin_name`; data, script and PNG in `dir`.
bool write_figures(const std::string& dir, const std::vector<ShearPoint>& points,
                   const ShearCalibration& all, const std::string& bin_name,
                   const std::vector<CalibrationBin>& bins) {
    if (::mkdir(dir.c_str(), 0777) != 0 && errno != EEXIST)
        throw Error("cannot create the figures' folder", dir);
    {
        AtomicTextFile data(dir + "/residuals.dat");
        data.stream().precision(17);
        data.stream() << "# component g_mean residual_mean residual_error galaxies\n";
        for (int component = 1; component <= 2; ++component) {
            std::vector<std::pair<double, double>> ge;
            for (const ShearPoint& p : points)
                ge.emplace_back(component == 1 ? p.g1 : p.g2,
                                component == 1 ? p.e1 - p.g1 : p.e2 - p.g2);
            std::sort(ge.begin(), ge.end());
            const std::size_t n = ge.size();
            for (std::size_t b = 0; b < 10; ++b) {
                const std::size_t lo = n * b / 10, hi = n * (b + 1) / 10;
                if (hi - lo < 2) continue;
                double sg = 0.0, sr = 0.0, srr = 0.0;
                for (std::size_t k = lo; k < hi; ++k)
                    sg += ge[k].first, sr += ge[k].second, srr += ge[k].second * ge[k].second;
                const double m = double(hi - lo), mean = sr / m;
                const double sd = std::sqrt(std::max(0.0, srr / m - mean * mean) * m / (m - 1.0));
                data.stream() << component << ' ' << sg / m << ' ' << mean << ' '
                              << sd / std::sqrt(m) << ' ' << hi - lo << '\n';
            }
            data.stream() << "\n\n";
        }
        data.commit();
    }
    {
        AtomicTextFile data(dir + "/bins.dat");
        data.stream().precision(17);
        data.stream() << "# " << bin_name << "_lo " << bin_name << "_hi m1 m1_error m2 m2_error\n";
        for (const CalibrationBin& b : bins)
            if (b.fit)
                data.stream() << b.lo << ' ' << b.hi << ' ' << b.fit->one.m << ' '
                              << b.fit->one.m_err << ' ' << b.fit->two.m << ' ' << b.fit->two.m_err
                              << '\n';
        data.commit();
    }
    // A column spanning decades (S/N, flux) on a log axis.
    const bool wide =
        !bins.empty() && bins.front().lo > 0.0 && bins.back().hi > 20.0 * bins.front().lo;
    {
        AtomicTextFile gp(dir + "/calibration.gp");
        gp.stream() << "# gnuplot " << dir << "/calibration.gp\n"
                    << "set terminal pngcairo size 1100,450 enhanced font 'DejaVu Sans,11'\n"
                    << "set output '" << dir << "/calibration.png'\n"
                    << "set multiplot layout 1,2\nset key top left\nset grid\n"
                    << "set xlabel 'true g'\nset ylabel '<e - g>'\n"
                    << "set title 'e = (1 + m) g + c: m_1 = " << cell(all.one.m, all.one.m_err)
                    << ", m_2 = " << cell(all.two.m, all.two.m_err) << "'\n"
                    << "plot '" << dir
                    << "/residuals.dat' index 0 using 2:3:4 with yerrorbars pt 7 lc 1 title 'e_1', "
                    << all.one.m << " * x + " << all.one.c << " lc 1 title 'fit 1', '" << dir
                    << "/residuals.dat' index 1 using 2:3:4 with yerrorbars pt 5 lc 2 title 'e_2', "
                    << all.two.m << " * x + " << all.two.c << " lc 2 title 'fit 2'\n"
                    << "set xlabel '" << bin_name << "' noenhanced\nset ylabel 'm'\n"
                    << "set title 'm in bins of "
                    << bin_name << "' noenhanced\n"
                    << (wide ? "set logscale x\n" : "")
                    << "plot '" << dir << "/bins.dat' using (sqrt(abs($1*$2))):3:4 "
                    << "with yerrorbars pt 7 lc 1 title 'm_1', '" << dir
                    << "/bins.dat' using (sqrt(abs($1*$2))):5:6 with yerrorbars pt 5 lc 2 "
                    << "title 'm_2', "
                    << "0 lc 0 notitle\nunset multiplot\n";
        gp.commit();
    }
    return app::run_gnuplot(dir + "/calibration.gp", dir + "/gnuplot.log");
}

int run(int argc, const char* const argv[]) {
    app::ProgramOptions options("shapesim-calibrate", "[OPTION]... TRUTH SHAPES [TRUTH SHAPES]...",
                                description,
                                app::Common::output | app::Common::quiet | app::Common::verbose |
                                    app::Common::config | app::Common::seed |
                                    app::Common::print_params);
    Settings s;
    using app::in_range;
    options.group("Catalogues").add_options()
        ("files", po::value(&s.files)->value_name("TRUTH SHAPES")->composing(),
         "a truth catalogue and the shape catalogue measured on its image; repeat the pair for "
         "more images")
        ("e1", po::value(&s.e1)->value_name("NAME")->default_value("e1"),
         "the shape catalogue's e1 column")
        ("e2", po::value(&s.e2)->value_name("NAME")->default_value("e2"),
         "the shape catalogue's e2 column")
        ("moments", po::value(&s.moments)->value_name("XX,YY,XY"),
         "the shape from second-moment columns instead of --e1/--e2 (SExtractor's windowed "
         "X2WIN_IMAGE,Y2WIN_IMAGE,XYWIN_IMAGE): e = (a−b)/(a+b) e^{2iθ} of their ellipse, not "
         "corrected for the PSF")
        ("position", po::value(&s.position)->value_name("X,Y")->default_value("x,y"),
         "its position columns: pixels of the image (or, with --sky, RA,DEC in degrees)")
        ("sky", po::bool_switch(&s.sky), "match on the sky (ra, dec) instead of in pixels")
        ("match-radius", po::value(&s.radius)->value_name("R")
             ->notifier(in_range("match-radius", 1e-9, 1e6)),
         "the farthest a measurement lies from its galaxy: pixels (default 2), or arcsec with "
         "--sky (default 0.2)")
        ("responsivity", po::value(&s.responsivity)->value_name("R")->default_value(1.0)
             ->notifier(in_range("responsivity", 1e-6, 1e6)),
         "divide e by this first (a distortion (a²−b²)/(a²+b²) responds to shear by about 2; a "
         "shear estimate by 1)")
        ("complete-rings", po::bool_switch(&s.complete_rings),
         "keep only rings (shapesim-sample --ring) whose every copy was measured: a ring with a "
         "copy lost (undetected, blended) no longer cancels its shape noise")
        ("flip-e2", po::bool_switch(&s.flip_e2),
         "e2 is in the sky's frame (east left): turn it into the image's (x right, y up)");
    options.group("Fit").add_options()
        ("bin", po::value(&s.bins)->value_name("NAME[:N]")->composing(),
         (std::string("also fit in N bins (default 4) of equal counts of this column (the "
                      "shape catalogue's, else the truth's: ") +
          truth_bin_list() + "); repeat for more (default: mag)")
             .c_str())
        ("bootstrap", po::value(&s.bootstrap)->value_name("N")->default_value(200)
             ->notifier(in_range("bootstrap", 0, 100000)),
         "bootstrap resamples for the errors")
        ("json", po::value(&s.json)->value_name("FILE"), "also write the numbers as JSON")
        ("figures", po::value(&s.figures)->value_name("DIR"),
         "also draw calibration.png there: <e - g> against g per component with the fitted "
         "line, and m against the first --bin (data and gnuplot script beside it)");
    options.positional("files", -1);
    if (!options.parse(argc, argv)) return 0;
    const app::Log log("shapesim-calibrate", options.common().verbosity);
    if (s.files.empty() || s.files.size() % 2 != 0)
        throw po::error("give pairs of files: TRUTH SHAPES [TRUTH SHAPES]...");
    const auto [px, py] = split_pair(s.position, "position");
    std::vector<std::string> moment_names;
    if (!s.moments.empty()) {
        if (options.given("e1") || options.given("e2"))
            throw po::error("--moments: not with --e1/--e2");
        std::istringstream names(s.moments);
        for (std::string name; std::getline(names, name, ',');) moment_names.push_back(name);
        if (moment_names.size() != 3 || std::any_of(moment_names.begin(), moment_names.end(),
                                                    [](const std::string& n) { return n.empty(); }))
            throw po::error("--moments: give three names, XX,YY,XY");
    }
    std::vector<Bin> bins;
    for (const std::string& b : s.bins) bins.push_back(parse_bin(b));
    if (s.bins.empty()) bins.push_back(Bin{"mag", 4});
    const double radius = options.given("match-radius") ? s.radius : s.sky ? 0.2 : 2.0;

    std::vector<std::string> optional;
    for (const Bin& b : bins) optional.push_back(b.name);
    // shapesim-measure's catalogues hold the uncorrected distortion as e1, e2 and the shear
    // estimate as shear_e1, shear_e2: calibrating the first by default would mislead.
    const bool e_defaulted = moment_names.empty() && !options.given("e1") && !options.given("e2");
    if (e_defaulted) optional.push_back("shear_e1");
    std::vector<ShearPoint> points;
    std::vector<long> ring_sizes;  // each point's ring's copies
    std::map<std::string, std::vector<double>> bin_values;
    long measured_total = 0, blends_or_strays = 0, truth_total = 0, without_shape = 0;
    std::optional<Wcs> plane;  // --sky: the tangent plane positions are matched on
    for (std::size_t f = 0; f < s.files.size(); f += 2) {
        const std::string& truth_path = s.files[f];
        const std::string& shapes_path = s.files[f + 1];
        const std::vector<TrueGalaxy> truth = read_truth(truth_path, f / 2, s.sky, plane);
        std::vector<std::string> wanted{px, py};
        if (moment_names.empty()) wanted.insert(wanted.end(), {s.e1, s.e2});
        else wanted.insert(wanted.end(), moment_names.begin(), moment_names.end());
        auto columns = read_numeric_columns(shapes_path, wanted, optional);
        // A bin's column is the shape catalogue's or one of the truth's fields.
        for (const Bin& b : bins)
            if (!columns.count(b.name) &&
                std::find(truth_bin_fields.begin(), truth_bin_fields.end(), b.name) ==
                    truth_bin_fields.end())
                throw Error("--bin " + b.name + ": no such column, nor a truth field (" +
                                truth_bin_list() + ")",
                            shapes_path);
        if (e_defaulted && columns.count("shear_e1"))
            log.info("note: ", shapes_path,
                     " has shear_e1, shear_e2 (shapesim-measure --shear-estimate): "
                     "its e1, e2 are the PSF-blurred distortion; calibrate the estimate with --e1 "
                     "shear_e1 --e2 shear_e2");
        std::vector<double> mx = columns.at(px), my = columns.at(py);
        std::vector<double> e1, e2;
        if (moment_names.empty()) {
            e1 = columns.at(s.e1);
            e2 = columns.at(s.e2);
        } else {
            // ε of the moments' ellipse: χ = (Qxx − Qyy + 2i Qxy)/(Qxx + Qyy),
            // ε = χ/(1 + √(1 − |χ|²)).
            const std::vector<double>& xx = columns.at(moment_names[0]);
            const std::vector<double>& yy = columns.at(moment_names[1]);
            const std::vector<double>& xy = columns.at(moment_names[2]);
            for (std::size_t k = 0; k < xx.size(); ++k) {
                const double t = xx[k] + yy[k], det = xx[k] * yy[k] - xy[k] * xy[k];
                double a = std::nan(""), b = std::nan("");
                if (t > 0.0 && det > 0.0) {
                    const double c1 = (xx[k] - yy[k]) / t, c2 = 2.0 * xy[k] / t;
                    const double d = 1.0 + std::sqrt(std::max(0.0, 1.0 - c1 * c1 - c2 * c2));
                    a = c1 / d, b = c2 / d;
                }
                e1.push_back(a);
                e2.push_back(b);
            }
        }
        // Rows without a position or a shape are no measurement.
        std::vector<std::size_t> rows;
        for (std::size_t k = 0; k < mx.size(); ++k)
            if (std::isfinite(mx[k]) && std::isfinite(my[k]) && std::isfinite(e1[k]) &&
                std::isfinite(e2[k]))
                rows.push_back(k);
        std::vector<double> qx, qy;
        for (std::size_t k : rows) {
            if (s.sky) {
                if (!plane) throw Error("no true galaxy to match", truth_path);
                const PixelPosition p = plane->sky_to_pixel(mx[k], my[k]);
                qx.push_back(p.x);
                qy.push_back(p.y);
            } else {
                qx.push_back(mx[k]);
                qy.push_back(my[k]);
            }
        }
        std::vector<double> tx, ty;
        for (const TrueGalaxy& g : truth) tx.push_back(g.x), ty.push_back(g.y);
        const std::vector<long> match = match_nearest(tx, ty, qx, qy, radius);
        long matched = 0;
        for (std::size_t q = 0; q < rows.size(); ++q) {
            if (match[q] < 0) {
                ++blends_or_strays;
                continue;
            }
            ++matched;
            const std::size_t k = rows[q];
            const TrueGalaxy& g = truth[std::size_t(match[q])];
            ShearPoint p;
            p.g1 = g.g1;
            p.g2 = g.g2;
            p.e1 = e1[k] / s.responsivity;
            p.e2 = (s.flip_e2 ? -e2[k] : e2[k]) / s.responsivity;
            p.block = g.block;
            points.push_back(p);
            ring_sizes.push_back(g.ring_size);
            for (const Bin& b : bins) {
                double v = std::nan("");
                if (const auto c = columns.find(b.name); c != columns.end()) v = c->second[k];
                else if (const auto t = g.fields.find(b.name); t != g.fields.end()) v = t->second;
                bin_values[b.name].push_back(v);
            }
        }
        measured_total += long(rows.size());
        without_shape += long(mx.size() - rows.size());
        truth_total += long(truth.size());
        log.verbose(shapes_path, ": ", matched, " of ", rows.size(), " measurements matched to ",
                    truth.size(), " true galaxies of ", truth_path);
    }
    long incomplete = 0;
    if (s.complete_rings) {
        std::map<std::uint64_t, long> matched;
        for (const ShearPoint& p : points) ++matched[p.block];
        std::vector<ShearPoint> kept;
        std::map<std::string, std::vector<double>> kept_values;
        for (std::size_t k = 0; k < points.size(); ++k) {
            if (matched[points[k].block] < ring_sizes[k]) {
                ++incomplete;
                continue;
            }
            kept.push_back(points[k]);
            for (auto& [name, values] : bin_values) kept_values[name].push_back(values[k]);
        }
        points = std::move(kept);
        bin_values = std::move(kept_values);
        log.verbose(incomplete, " matched galaxies in rings with a copy lost left out");
    }
    const std::uint64_t seed = options.common().seed;
    const ShearCalibration all = fit_shear_calibration(points, s.bootstrap, seed);

    std::ostringstream md;
    md << "# Shear calibration\n\n"
       << "e = (1 + m) g + c per component, least squares over " << all.galaxies
       << " matched galaxies (" << all.blocks << " bootstrap blocks, " << s.bootstrap
       << " resamples; errors 1σ). " << measured_total << " measurements of " << truth_total
       << " true galaxies in " << s.files.size() / 2 << " image(s)"
       << (without_shape
               ? " (and " + std::to_string(without_shape) + " rows without a position or a shape)"
               : "")
       << "; " << blends_or_strays << " measurements unmatched within " << radius
       << (s.sky ? "\"" : " px") << " (blends, spurious detections); responsivity "
       << s.responsivity
       << (s.complete_rings
               ? "; " + std::to_string(incomplete) + " galaxies of rings with a copy lost left out"
               : "")
       << ".\n\n"
       << "| component | m | c |\n|---|---|---|\n"
       << "| 1 | " << cell(all.one.m, all.one.m_err) << " | " << cell(all.one.c, all.one.c_err)
       << " |\n"
       << "| 2 | " << cell(all.two.m, all.two.m_err) << " | " << cell(all.two.c, all.two.c_err)
       << " |\n";
    Json json{{"all", fit_json(all)}, {"matched", all.galaxies}, {"measured", measured_total},
              {"true_galaxies", truth_total}, {"unmatched", blends_or_strays},
              {"match_radius", radius}, {"responsivity", s.responsivity},
              {"incomplete_rings_left_out", incomplete}, {"bins", Json::object()}};
    std::vector<CalibrationBin> first_bins;  // the figure's
    for (const Bin& b : bins) {
        const std::vector<double>& v = bin_values[b.name];
        long defined = 0;
        for (double x : v) defined += std::isfinite(x) ? 1 : 0;
        md << "\n## By " << b.name << "\n\n";
        if (defined == 0) {
            md << "No matched galaxy has a value of " << b.name << ".\n";
            log.info("no matched galaxy has a value of ", b.name, ": no bins");
            continue;
        }
        md << "| " << b.name << " | galaxies | m1 | c1 | m2 | c2 |\n|---|---|---|---|---|---|\n";
        Json rows = Json::array();
        const std::vector<CalibrationBin> fitted =
            fit_in_bins(points, v, b.count, s.bootstrap, seed);
        if (&b == &bins.front()) first_bins = fitted;
        for (const CalibrationBin& bin : fitted) {
            char range[64];
            std::snprintf(range, sizeof range, "%.4g – %.4g", bin.lo, bin.hi);
            md << "| " << range << " | " << bin.galaxies << " | ";
            Json row{{"lo", bin.lo}, {"hi", bin.hi}, {"galaxies", bin.galaxies}};
            if (bin.fit) {
                md << cell(bin.fit->one.m, bin.fit->one.m_err) << " | "
                   << cell(bin.fit->one.c, bin.fit->one.c_err) << " | "
                   << cell(bin.fit->two.m, bin.fit->two.m_err) << " | "
                   << cell(bin.fit->two.c, bin.fit->two.c_err) << " |\n";
                row["fit"] = fit_json(*bin.fit);
            } else {
                md << "– | – | – | – |\n";
            }
            rows.push_back(row);
        }
        json["bins"][b.name] = rows;
    }
    if (!s.figures.empty()) {
        if (write_figures(s.figures, points, all, bins.front().name, first_bins))
            log.info("figure: ", s.figures, "/calibration.png");
        else
            log.warn("gnuplot not found: the figure not drawn (run gnuplot ", s.figures,
                     "/calibration.gp)");
    }
    if (!s.json.empty()) {
        AtomicTextFile file(s.json);
        file.stream() << json.dump(1) << '\n';
        file.commit();
    }
    AtomicTextFile report(options.common().output_or_stdout());
    report.stream() << md.str();
    report.commit();
    log.info(all.galaxies, " galaxies: m1 ", cell(all.one.m, all.one.m_err), ", c1 ",
             cell(all.one.c, all.one.c_err), "; m2 ", cell(all.two.m, all.two.m_err), ", c2 ",
             cell(all.two.c, all.two.c_err));
    return 0;
}

}  // namespace

int main(int argc, char** argv) { return app::run_main(argc, argv, "shapesim-calibrate", run); }
