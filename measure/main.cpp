// shapesim-measure: the morphology diagnostics of every galaxy of an image (paper §5,
// DESIGN §5) as shapesim.morph/1 records. Detection is shapesim-detect's own
// (app/detection_run.hpp), the statistics are measure.hpp / morphometry.hpp.
#include "shapesim/app/atomic_file.hpp"
#include "shapesim/app/detection_run.hpp"
#include "shapesim/app/options.hpp"
#include "shapesim/app/progress.hpp"
#include "shapesim/app/run_main.hpp"
#include "shapesim/colours.hpp"
#include "shapesim/compare.hpp"
#include "shapesim/noise.hpp"
#include "shapesim/error.hpp"
#include "shapesim/jsonl.hpp"
#include "shapesim/measure.hpp"
#include "shapesim/parallel.hpp"
#include "shapesim/stellarity.hpp"

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sys/stat.h>
#include <iostream>
#include <thread>

namespace {

using namespace shapesim;
namespace po = app::po;

const char* const description =
    "Detect the objects of an image exactly as shapesim-detect does and measure, per galaxy:\n"
    "Kron magnitude, FWHM, a, b, theta, e1, e2 (paper eqs. 6-7), stellarity, the Petrosian\n"
    "radius (eta = 0.2), concentration C, asymmetry A, clumpiness S (x10, Conselice 2003),\n"
    "Gini and M20, defined as statmorph defines them, with flags where a statistic is\n"
    "unreliable (small, faint, crowded, no_sky). Records go to stdout as shapesim.morph/1.\n"
    "\n"
    "\n"
    "With --compare NAME=FILE ... (measured catalogues; the first is the reference), write to\n"
    "--out DIR: table.md (the paper's Table: mean and rms of C, A, S, rms e, median and sd\n"
    "of the FWHM, with bootstrap errors), distances.md (KS statistic and p-value, 1D\n"
    "Wasserstein distance of each catalogue from the first, per statistic) and, with\n"
    "gnuplot, the figures of the paper's Figs. 5-11 as PNG.\n"
    "\n"
    "Examples (the shipped HDF-N data):\n"
    "  shapesim-measure hdfn_f814w_v2.fits --weight hdfn_f814w_v2_weight.fits \\\n"
    "      --zero-point 22.08 -j 2 > hdf.morph.jsonl\n"
    "  shapesim-measure --compare hdf=hdf.morph.jsonl sim=sim.morph.jsonl --out report";

// --compare: the Table, the distances and the figures.
struct CompareSettings {
    std::vector<std::string> inputs, skies, colours;
    std::string out = "compare", paper;
    std::string band = "I";  // the magnitudes' band, as the Table and figures label the cuts
    TableCuts cuts;
};

std::string format(double v, double err, int digits = 3) {
    char buf[64];
    if (!std::isfinite(v)) return "–";
    if (std::isfinite(err)) std::snprintf(buf, sizeof buf, "%.*f ± %.*f", digits, v, digits, err);
    else std::snprintf(buf, sizeof buf, "%.*f", digits, v);
    return buf;
}

int run_compare(const CompareSettings& c, const app::Log& log) {
    std::vector<Catalogue> catalogues;
    for (const auto& [name, path] : app::named_files(c.inputs, "compare")) {
        Catalogue cat;
        cat.name = name;
        JsonlReader reader(path, {MorphRecord::schema});
        Json record;
        while (reader.next(record)) {
            try {
                MorphRecord::from_json(record);  // the schema's own checks, placed
            } catch (const Error& e) {
                throw reader.locate(e);
            }
            cat.records.push_back(record);
        }
        if (cat.records.empty()) throw Error("no records to compare", reader.name());
        catalogues.push_back(std::move(cat));
    }
    if (catalogues.size() < 2) throw po::error("--compare needs at least two catalogues");
    std::vector<TableRow> rows;
    for (const Catalogue& cat : catalogues) rows.push_back(table_row(cat, c.cuts));
    if (!c.paper.empty()) {
        JsonlReader reader(c.paper, {"shapesim.table_row/1"});
        Json record;
        while (reader.next(record)) {
            try {
                rows.push_back(table_row_from_json(record));
            } catch (const Error& e) {
                throw reader.locate(e);
            }
        }
    }
    if (::mkdir(c.out.c_str(), 0777) != 0 && errno != EEXIST)
        throw Error("cannot create the output folder", c.out);

    {
        app::AtomicTextFile table(c.out + "/table.md");
        auto& o = table.stream();
        o << "| catalogue | N (" << c.band << " ≤ " << c.cuts.mag_counts << ") | ⟨C⟩ | rms C | ⟨A⟩ | rms A | ⟨S⟩ | rms S"
          << " | rms e | FWHM median (″) | FWHM sd (″) |\n|---|---|---|---|---|---|---|---|---|---|---|\n";
        for (const TableRow& t : rows) {
            o << "| " << t.name << " | " << (t.galaxies >= 0 ? std::to_string(t.galaxies) : "–")
              << " | " << format(t.c_mean, t.c_mean_err)
              << " | " << format(t.c_rms, t.c_rms_err) << " | " << format(t.a_mean, t.a_mean_err)
              << " | " << format(t.a_rms, t.a_rms_err) << " | " << format(t.s_mean, t.s_mean_err)
              << " | " << format(t.s_rms, t.s_rms_err) << " | " << format(t.e_rms, t.e_rms_err)
              << " | " << format(t.fwhm_median, t.fwhm_median_err) << " | "
              << format(t.fwhm_sd, t.fwhm_sd_err) << " |\n";
        }
        o << "\nC and A for " << c.band << " ≤ " << c.cuts.mag_ca << ", S (×10, Conselice 2003) for "
          << c.band << " ≤ " << c.cuts.mag_s << ", e and FWHM for " << c.band
          << " ≤ " << c.cuts.mag_counts << "; errors: "
          << c.cuts.resamples << " bootstrap resamples.\n";
        table.commit();
    }
    {
        app::AtomicTextFile distances(c.out + "/distances.md");
        auto& o = distances.stream();
        o << "| statistic | catalogue | n | n (" << catalogues[0].name
          << ") | KS D | KS p | Wasserstein |\n|---|---|---|---|---|---|---|\n";
        const std::pair<const char*, double> stats[] = {
            {"mag", c.cuts.mag_counts}, {"fwhm_arcsec", c.cuts.mag_counts}, {"e", c.cuts.mag_counts},
            {"r_petro", c.cuts.mag_ca}, {"c", c.cuts.mag_ca}, {"a_sym", c.cuts.mag_ca},
            {"s", c.cuts.mag_s}, {"gini", c.cuts.mag_ca}, {"m20", c.cuts.mag_ca}};
        for (const auto& [field, limit] : stats) {
            const std::vector<double> ref = catalogues[0].column(field, limit);
            for (std::size_t k = 1; k < catalogues.size(); ++k) {
                const std::vector<double> v = catalogues[k].column(field, limit);
                o << "| " << field << " | " << catalogues[k].name << " | " << v.size() << " | "
                  << ref.size() << " | ";
                if (v.empty() || ref.empty()) {
                    o << "– | – | – |\n";
                    continue;
                }
                const KsResult ks = ks_two_sample(ref, v);
                char buf[128];
                std::snprintf(buf, sizeof buf, "%.3f | %.3g | %.4g |\n", ks.d, ks.p_value,
                              wasserstein_1d(ref, v));
                o << buf;
            }
        }
        distances.commit();
    }
    // Figures: data per catalogue, one gnuplot script, run when gnuplot is there.
    for (std::size_t k = 0; k < catalogues.size(); ++k) {
        app::AtomicTextFile data(c.out + "/" + catalogues[k].name + ".dat");
        auto& o = data.stream();
        o << "# mag fwhm_arcsec e c a_sym s r_petro_arcsec\n";
        for (const Json& r : catalogues[k].records) {
            if (r.contains("kind") && r.at("kind") != "galaxy") continue;
            auto num = [&](const char* key) {
                return r.contains(key) && r.at(key).is_number() ? r.at(key).get<double>()
                                                               : std::numeric_limits<double>::quiet_NaN();
            };
            const double scale = num("pixel_scale");
            const double values[] = {num("mag"), num("fwhm") * scale, std::hypot(num("e1"), num("e2")),
                                     num("c"), num("a_sym"), num("s"), num("r_petro") * scale};
            for (double v : values) {
                if (std::isfinite(v)) o << v << ' ';
                else o << "NaN ";
            }
            o << '\n';
        }
        data.commit();
    }
    {
        app::AtomicTextFile script(c.out + "/figures.gp");
        auto& o = script.stream();
        o << "# gnuplot " << c.out << "/figures.gp (run from the parent folder)\n"
          << "set terminal pngcairo size 640,480 enhanced font 'DejaVu Sans,11'\nset key top left\n"
          << "set datafile missing 'NaN'\nbin(x, w) = w * floor(x / w) + w / 2.0\n";
        auto plot = [&](const char* name, const std::string& setup, const std::string& each) {
            o << "set output '" << c.out << "/" << name << ".png'\n" << setup << "\nplot ";
            for (std::size_t k = 0; k < catalogues.size(); ++k) {
                std::string line = each;
                const std::string file = "'" + c.out + "/" + catalogues[k].name + ".dat'";
                for (std::size_t p; (p = line.find("FILE")) != std::string::npos;) line.replace(p, 4, file);
                for (std::size_t p; (p = line.find("NAME")) != std::string::npos;)
                    line.replace(p, 4, catalogues[k].name);
                o << (k ? ", \\\n     " : "") << line;
            }
            o << "\nunset logscale\n";
        };
        const std::string mcut = std::to_string(c.cuts.mag_counts), ca = std::to_string(c.cuts.mag_ca),
                          scut = std::to_string(c.cuts.mag_s);
        plot("counts", "set title 'Number counts (Fig. 5)'\nset xlabel 'I'\nset ylabel 'N per 0.5 mag'\nset logscale y",
             "FILE using (bin($1,0.5)):(1.0) smooth frequency with histeps title 'NAME'");
        plot("size", "set title 'Size distribution, " + c.band + " <= " + mcut + " (Fig. 6)'\nset xlabel 'FWHM (arcsec)'\nset ylabel 'N'",
             "FILE using ($1 <= " + mcut + " ? bin($2,0.05) : NaN):(1.0) smooth frequency with histeps title 'NAME'");
        plot("size_mag", "set title 'Size against magnitude (Fig. 7)'\nset xlabel 'I'\nset ylabel 'FWHM (arcsec)'\nset logscale y",
             "FILE using 1:2 with points pt 7 ps 0.4 title 'NAME'");
        plot("ellipticity", "set title 'Ellipticity, " + c.band + " <= " + mcut + " (Fig. 8)'\nset xlabel '|e|'\nset ylabel 'N'",
             "FILE using ($1 <= " + mcut + " ? bin($3,0.05) : NaN):(1.0) smooth frequency with histeps title 'NAME'");
        plot("c_a", "set title 'Concentration against asymmetry, " + c.band + " <= " + ca + " (Fig. 9)'\nset xlabel 'A'\nset ylabel 'C'",
             "FILE using ($1 <= " + ca + " ? $5 : NaN):4 with points pt 7 ps 0.6 title 'NAME'");
        plot("c_rp", "set title 'Concentration against Petrosian radius, " + c.band + " <= " + ca + " (Fig. 10)'\nset xlabel 'r_p (arcsec)'\nset ylabel 'C'",
             "FILE using ($1 <= " + ca + " ? $7 : NaN):4 with points pt 7 ps 0.6 title 'NAME'");
        plot("a_s", "set title 'Asymmetry against clumpiness, " + c.band + " <= " + scut + " (Fig. 11)'\nset xlabel 'S'\nset ylabel 'A'",
             "FILE using ($1 <= " + scut + " ? $6 : NaN):5 with points pt 7 ps 0.6 title 'NAME'");
        script.commit();
    }
    if (std::system("command -v gnuplot >/dev/null 2>&1") == 0) {
        // gnuplot's own chatter (e.g. "empty y range" for a constant statistic) goes to a log
        // beside the figures: stderr keeps to our one-line messages.
        const std::string command =
            "gnuplot '" + c.out + "/figures.gp' 2>'" + c.out + "/gnuplot.log'";
        if (std::system(command.c_str()) != 0)
            throw Error("gnuplot failed on the figures (see gnuplot.log there)",
                        c.out + "/figures.gp");
        log.info("table, distances and 7 figures in ", c.out, "/");
    } else {
        log.warn("gnuplot not found: figures not drawn (run gnuplot ", c.out, "/figures.gp)");
    }
    return 0;
}

int run(int argc, const char* const argv[]) {
    app::ProgramOptions options("shapesim-measure", "[OPTION]... IMAGE", description,
                                app::Common::quiet | app::Common::verbose | app::Common::threads |
                                    app::Common::config | app::Common::print_params);
    app::DetectionSettings detection;
    MeasureOptions measure;
    CompareSettings compare;
    bool stars = false;
    double mag_limit = 0.0;
    detection.declare(options, false);
    using app::in_range;
    options.group("Statistics").add_options()
        ("with-stars", po::bool_switch(&stars), "also measure the stars (kind \"star\")")
        ("mag-limit", po::value(&mag_limit)->value_name("MAG")->notifier(in_range("mag-limit", -100.0, 100.0)),
         "leave out objects fainter than this Kron magnitude (and those without one)")
        ("min-petrosian", po::value(&measure.min_petrosian)->default_value(2.0)
             ->notifier(in_range("min-petrosian", 0.0, 1e6)),
         "flag \"small\" below this Petrosian radius, pixels")
        ("min-snr", po::value(&measure.min_snr)->default_value(10.0)
             ->notifier(in_range("min-snr", 0.0, 1e12)), "flag \"faint\" below this Kron S/N")
        ("max-neighbour-fraction", po::value(&measure.max_neighbour_fraction)->default_value(0.1)
             ->notifier(in_range("max-neighbour-fraction", 0.0, 1.0)),
         "flag \"crowded\" above this fraction of neighbours' pixels in the CAS aperture")
        ("statmorph-boxcar", po::bool_switch(&measure.morphometry.statmorph_boxcar),
         "S with statmorph's own (even, off-centre) boxcar");
    options.group("Compare").add_options()
        ("compare", po::value(&compare.inputs)->value_name("NAME=FILE")->multitoken(),
         "compare measured catalogues (the first is the reference) instead of measuring")
        ("compare-colours", po::value(&compare.colours)->value_name("NAME=FILE")->multitoken(),
         "compare the colours of source catalogues of shapesim-detect --bands (the first is "
         "the reference; galaxies brighter than --mag-limit): a markdown report on stdout")
        ("compare-sky", po::value(&compare.skies)->value_name("NAME=FILE")->multitoken(),
         "compare skies' noise records (shapesim-detect --noise-model; the first is the "
         "reference): a markdown table on stdout")
        ("out", po::value(&compare.out)->value_name("DIR")->default_value("compare"),
         "folder for table.md, distances.md and the figures")
        ("paper", po::value(&compare.paper)->value_name("FILE"),
         "published rows to add to the Table (JSON lines: name, c_mean, c_rms, ...; e.g.\n"
         "share/data/paper/massey2004_table.jsonl)")
        ("band", po::value(&compare.band)->value_name("NAME")->default_value("I")
             ->notifier([](const std::string& band) {
                 // It is written into gnuplot's quoted titles: a plain name only.
                 if (band.empty() || band.size() > 16 ||
                     band.find_first_not_of("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz"
                                            "0123456789_-+") != std::string::npos)
                     throw po::error("--band takes a plain name (letters, digits, _-+), got '" +
                                     band + "'");
             }),
         "the magnitudes' band, as the Table and the figures name their cuts (the paper's: "
         "HST F814W, I)")
        ("mag-counts", po::value(&compare.cuts.mag_counts)->default_value(29.0),
         "magnitude limit for counts, sizes and ellipticities")
        ("mag-ca", po::value(&compare.cuts.mag_ca)->default_value(26.0),
         "magnitude limit for C and A (and Gini, M20, r_p)")
        ("mag-s", po::value(&compare.cuts.mag_s)->default_value(25.0), "magnitude limit for S")
        ("bootstrap", po::value(&compare.cuts.resamples)->default_value(1000)
             ->notifier(in_range("bootstrap", 2, 1000000)), "bootstrap resamples for the errors");
    if (!options.parse(argc, argv)) return 0;
    const app::Log log("shapesim-measure", options.common().verbosity);
    if (!compare.colours.empty()) {
        if (!detection.image.empty() || !compare.inputs.empty() || !compare.skies.empty())
            throw po::error("--compare-colours: not with an IMAGE, --compare or --compare-sky");
        std::vector<ColourCatalogue> catalogues;
        for (const auto& [name, path] : app::named_files(compare.colours, "compare-colours")) {
            JsonlReader reader(path, {SourceRecord::schema});
            try {
                catalogues.push_back(ColourCatalogue::from_records(
                    name, reader.read_all<SourceRecord>(options.common().threads)));
            } catch (const Error& e) {
                throw e.at(path, 0);
            }
        }
        const double limit = options.given("mag-limit") ? mag_limit : 99.0;
        write_colour_report(std::cout, catalogues,
                            compare_colours(catalogues, limit, compare.cuts.resamples, 0), limit);
        return 0;
    }
    if (!compare.skies.empty()) {
        if (!detection.image.empty() || !compare.inputs.empty())
            throw po::error("--compare-sky: not with an IMAGE or --compare");
        std::vector<std::string> names;
        std::vector<NoiseRecord> skies;
        for (const auto& [name, path] : app::named_files(compare.skies, "compare-sky")) {
            names.push_back(name);
            skies.push_back(read_noise_record(path));
        }
        write_sky_table(std::cout, names, skies);
        return 0;
    }
    if (!compare.inputs.empty()) {
        if (!detection.image.empty()) throw po::error("give an IMAGE or --compare, not both");
        return run_compare(compare, log);
    }
    if (detection.image.empty()) throw po::error("give an IMAGE to measure (or --compare)");

    const app::DetectionRun detected = detection.run(options, log);
    const DetectionResult& field = detected.field;
    struct Job {
        const Detection* object;
        SourceRecord source;
        std::optional<MorphRecord> record;
        std::string error;
    };
    std::vector<Job> jobs;
    long too_faint = 0;
    for (const Detection& object : field.objects) {
        if (is_single_pixel_event(object.peak, object.flux_iso)) continue;  // a cosmic ray
        const CoreFraction core = core_fraction(field, object, detected.locus);
        const double star = stellarity(core, detected.locus);
        if (star > detection.star_threshold && !stars) continue;
        SourceRecord source = source_record(object, core, star, nullptr, detected.context);
        // Fainter than every cut of the comparison: not worth the statistics (nor a record).
        if (options.given("mag-limit") && !(source.mag && *source.mag <= mag_limit)) {
            ++too_faint;
            continue;
        }
        jobs.push_back({&object, std::move(source), {}, {}});
    }
    app::Progress progress(log, "measured", "objects", jobs.size());
    parallel_for(jobs.size(), options.common().threads, [&](std::size_t k, int) {
        try {
            jobs[k].record = measure_object(field, *jobs[k].object, jobs[k].source, measure);
            jobs[k].record->extra["pixel_scale"] = detected.context.pixel_scale;
        } catch (const std::exception& e) {
            jobs[k].error = e.what();
        }
        progress.done_one();
    });

    JsonlWriter out(std::cout, "-");
    long skipped = 0;
    for (const Job& job : jobs) {
        if (!job.record) {
            ++skipped;
            log.warn("object ", job.source.id, ": ", job.error);
            continue;
        }
        out.write(job.record->to_json());
    }
    log.info(out.count(), " objects measured", skipped ? ", " + std::to_string(skipped) + " skipped" : "",
             too_faint ? ", " + std::to_string(too_faint) + " fainter than --mag-limit left out" : "",
             " in ", log.elapsed(), " s; stars (left out) through ", detected.locus_note);
    return 0;
}

}  // namespace

int main(int argc, char** argv) { return app::run_main(argc, argv, "shapesim-measure", run); }
