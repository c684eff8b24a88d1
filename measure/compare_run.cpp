#include "measure/compare_run.hpp"

#include "app/gnuplot.hpp"
#include "shapesim/atomic_file.hpp"
#include "shapesim/colours.hpp"
#include "shapesim/error.hpp"
#include "shapesim/jsonl.hpp"
#include "shapesim/measure.hpp"
#include "shapesim/noise.hpp"

#include <sys/stat.h>
#include <cerrno>
#include <cstdlib>

namespace shapesim::app {

namespace {

// The --compare catalogues, each record checked against shapesim.morph/1.
std::vector<Catalogue> read_catalogues(const std::vector<std::string>& specs) {
    std::vector<Catalogue> catalogues;
    for (const auto& [name, path] : named_files(specs, "compare")) {
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
    return catalogues;
}

// --paper's published rows (shapesim.table_row/1), appended to `rows`.
void read_paper_rows(const std::string& path, std::vector<TableRow>& rows) {
    JsonlReader reader(path, {"shapesim.table_row/1"});
    Json record;
    while (reader.next(record)) {
        try {
            rows.push_back(table_row_from_json(record));
        } catch (const Error& e) {
            throw reader.locate(e);
        }
    }
}

// One file of the report, whole or not at all.
template <class Write>
void write_file(const std::string& path, Write write) {
    AtomicTextFile file(path);
    write(file.stream());
    file.commit();
}

}  // namespace

void CompareSettings::declare(ProgramOptions& options) {
    options.group("Compare").add_options()
        ("compare", po::value(&inputs)->value_name("NAME=FILE")->multitoken(),
         "compare measured catalogues (the first is the reference) instead of measuring")
        ("compare-colours", po::value(&colours)->value_name("NAME=FILE")->multitoken(),
         "compare the colours of source catalogues of shapesim-detect --bands (the first is "
         "the reference; galaxies brighter than --mag-limit): a markdown report on stdout")
        ("compare-sky", po::value(&skies)->value_name("NAME=FILE")->multitoken(),
         "compare skies' noise records (shapesim-detect --noise-model; the first is the "
         "reference): a markdown table on stdout")
        ("compare-paired", po::value(&paired)->value_name("NAME=FILE")->multitoken(),
         "pair the real catalogue (the first) galaxy by galaxy with replays of its field (the\n"
         "others: shapesim-sample --replay, rendered and measured alike; several seeds): the\n"
         "FWHM ratios by magnitude, a markdown table on stdout")
        ("pair-radius", po::value(&pair_radius)->default_value(0.1)
             ->notifier(in_range("pair-radius", 1e-6, 3600.0)),
         "arcsec: a replay's galaxy this near a real one is its pair")
        ("paper", po::value(&paper)->value_name("FILE"),
         "published rows to add to the Table (JSON lines: name, c_mean, c_rms, ...; e.g.\n"
         "share/data/paper/massey2004_table.jsonl)")
        ("band", po::value(&band)->value_name("NAME")->default_value("I")
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
        ("mag-counts", po::value(&cuts.mag_counts)->default_value(29.0),
         "magnitude limit for counts, sizes and ellipticities")
        ("mag-ca", po::value(&cuts.mag_ca)->default_value(26.0),
         "magnitude limit for C and A (and Gini, M20, r_p)")
        ("mag-s", po::value(&cuts.mag_s)->default_value(25.0), "magnitude limit for S")
        ("bootstrap", po::value(&cuts.resamples)->default_value(1000)
             ->notifier(in_range("bootstrap", 2, 1000000)), "bootstrap resamples for the errors");
    options.group("Output").add_options()
        ("output,o", po::value<std::string>()->value_name("FILE"),
         "write the catalogue (or a --compare-colours/--compare-sky report) to FILE instead of "
         "stdout, as FILE.tmp.<pid> renamed when complete; with --compare: the folder for "
         "table.md, distances.md and the figures (default: compare)");
    options.alias("out", "output");
}

void CompareSettings::write_report(const Log& log) const {
    const std::vector<Catalogue> catalogues = read_catalogues(inputs);
    if (catalogues.size() < 2) throw po::error("--compare needs at least two catalogues");
    std::vector<TableRow> rows;
    for (const Catalogue& cat : catalogues) rows.push_back(table_row(cat, cuts));
    if (!paper.empty()) read_paper_rows(paper, rows);
    if (::mkdir(out.c_str(), 0777) != 0 && errno != EEXIST)
        throw Error("cannot create the output folder", out);

    write_file(out + "/table.md",
               [&](std::ostream& o) { write_table_markdown(o, rows, band, cuts); });
    write_file(out + "/distances.md",
               [&](std::ostream& o) { write_distances_markdown(o, catalogues, cuts); });
    // Figures: data per catalogue, one gnuplot script, run when gnuplot is there.
    for (const Catalogue& cat : catalogues)
        write_file(out + "/" + cat.name + ".dat",
                   [&](std::ostream& o) { write_figure_data(o, cat); });
    write_file(out + "/figures.gp",
               [&](std::ostream& o) { write_figures_script(o, out, catalogues, band, cuts); });
    if (run_gnuplot(out + "/figures.gp", out + "/gnuplot.log")) {
        log.info("table, distances and 7 figures in ", out, "/");
    } else {
        log.warn("gnuplot not found: figures not drawn (run gnuplot ", out, "/figures.gp)");
    }
}

void CompareSettings::write_colours(std::ostream& o, double mag_limit, int threads) const {
    std::vector<ColourCatalogue> catalogues;
    for (const auto& [name, path] : named_files(colours, "compare-colours")) {
        JsonlReader reader(path, {SourceRecord::schema});
        try {
            catalogues.push_back(
                ColourCatalogue::from_records(name, reader.read_all<SourceRecord>(threads)));
        } catch (const Error& e) {
            throw e.at(path, 0);
        }
    }
    write_colour_report(o, catalogues, compare_colours(catalogues, mag_limit, cuts.resamples, 0),
                        mag_limit);
}

void CompareSettings::write_paired(std::ostream& o) const {
    const std::vector<Catalogue> catalogues = read_catalogues(paired);
    if (catalogues.size() < 2)
        throw po::error("--compare-paired needs the real catalogue and at least one replay");
    const std::vector<Catalogue> replays(catalogues.begin() + 1, catalogues.end());
    write_paired_markdown(o, compare_paired(catalogues.front(), replays, pair_radius, cuts), band,
                          cuts);
}

void CompareSettings::write_skies(std::ostream& o) const {
    std::vector<std::string> names;
    std::vector<NoiseRecord> noise;
    for (const auto& [name, path] : named_files(skies, "compare-sky")) {
        names.push_back(name);
        noise.push_back(read_noise_record(path));
    }
    write_sky_table(o, names, noise);
}

}  // namespace shapesim::app
