// shapesim-decompose: shapesim.source/1 records + their stamps → shapesim.shapelet/1 models
// with optimised centre, β and n_max (paper §2.2; DESIGN §1–3). The work is in the library:
// decompose.hpp (the optimiser and the record), lsq.hpp (the linear fit).
#include "shapesim/app/atomic_file.hpp"
#include "shapesim/app/options.hpp"
#include "shapesim/app/run_main.hpp"
#include "shapesim/decompose.hpp"
#include "shapesim/error.hpp"
#include "shapesim/fits_io.hpp"
#include "shapesim/jsonl.hpp"
#include "shapesim/records.hpp"

#include <atomic>
#include <exception>
#include <iostream>
#include <map>
#include <memory>
#include <set>
#include <thread>

namespace {

using namespace shapesim;
namespace po = app::po;

const char* const description =
    "Fit each postage stamp with a polar shapelet series, choosing the centre (the model's\n"
    "own centroid), the scale beta (a search on chi2_r within the resolution and stamp\n"
    "limits) and n_max (raised until chi2_r <= 1, capped at 15). Reads shapesim.source/1\n"
    "records on stdin and the stamps shapesim-detect wrote; writes shapesim.shapelet/1.\n"
    "\n"
    "Example (after shapesim-detect ... --stamps stamps.fits > sources.jsonl):\n"
    "  shapesim-decompose --stamps stamps.fits -j 2 < sources.jsonl > shapelets.jsonl";

struct Settings {
    std::string stamps, models, ids;
    std::string input = "-";
    bool ignore_correlation = false;
    double noise_correlation = 0.0;
    DecomposeOptions fit;
};

void declare(app::ProgramOptions& options, Settings& s) {
    using app::in_range;
    DecomposeOptions& f = s.fit;
    options.group("Input").add_options()
        ("input,i", po::value(&s.input)->value_name("FILE")->default_value("-"),
         "source records (default: stdin)")
        ("stamps", po::value(&s.stamps)->value_name("FILE"),
         "stamps file (default: each record's stamp_file)");
    options.group("Optimiser").add_options()
        ("n-max-cap", po::value(&f.n_max_cap)->default_value(15)
             ->notifier(in_range("n-max-cap", 0, 100)), "highest n_max")
        ("n-max-min", po::value(&f.n_max_min)->default_value(0)
             ->notifier(in_range("n-max-min", 0, 100)), "first n_max tried")
        ("chi2-target", po::value(&f.chi2_target)->default_value(1.0)
             ->notifier(in_range("chi2-target", 1e-6, 1e6)), "stop when chi2_r reaches this")
        ("chi2-sigmas", po::value(&f.chi2_sigmas)->default_value(2.0)
             ->notifier(in_range("chi2-sigmas", 0.0, 100.0)),
         "accept chi2_r up to the target plus this many sigma of its noise, sqrt(2/dof)")
        ("beta-tolerance", po::value(&f.beta_tolerance)->default_value(1e-3)
             ->notifier(in_range("beta-tolerance", 1e-8, 0.5)),
         "tolerance of the beta search, in ln beta")
        ("theta-min", po::value(&f.theta_min)->default_value(1.0)
             ->notifier(in_range("theta-min", 1e-3, 1e3)),
         "smallest scale beta/sqrt(n_max+1) the basis may resolve, pixels")
        ("flatten", po::value(&f.flatten_fraction)->default_value(0.01)
             ->notifier(in_range("flatten", 0.0, 1.0)),
         "stop when chi2_r falls by less than this fraction over two orders")
        ("noise-correlation", po::value(&s.noise_correlation)->value_name("F")
             ->notifier(in_range("noise-correlation", 1.0, 100.0)),
         "correlated-noise factor for the effective degrees of freedom (default: the "
         "record's noise_correlation from shapesim-detect, else 1)")
        ("white-noise", po::bool_switch(&s.ignore_correlation),
         "use the textbook chi2_r (F = 1) even when the record has a factor");
    options.group("Output").add_options()
        ("models", po::value(&s.models)->value_name("FILE"),
         "write data, model and residual images (<id>.data/.model/.residual) to this FITS file")
        ("ids", po::value(&s.ids)->value_name("LIST"),
         "with --models: only these ids (comma-separated; default all)");
}

struct Job {
    SourceRecord source;
    Stamp stamp;
    double noise_correlation = 1.0;
    long line = 0;
};

struct Outcome {
    std::optional<ShapeletRecord> record;
    std::optional<Decomposition> decomposition;
    std::string error;  // non-empty: the stamp could not be fitted at all
};

std::set<std::string> split_ids(const std::string& list) {
    std::set<std::string> ids;
    std::string id;
    for (char c : list + ",") {
        if (c == ',') {
            if (!id.empty()) ids.insert(id);
            id.clear();
        } else if (c != ' ') {
            id += c;
        }
    }
    return ids;
}

int run(int argc, const char* const argv[]) {
    app::ProgramOptions options("shapesim-decompose", "[OPTION]...", description,
                                app::Common::quiet | app::Common::verbose | app::Common::threads |
                                    app::Common::config | app::Common::print_params);
    Settings s;
    declare(options, s);
    if (!options.parse(argc, argv)) return 0;
    const app::Log log("shapesim-decompose", options.common().verbosity);
    s.fit.validate();
    if (!s.ids.empty() && s.models.empty()) throw po::error("--ids needs --models");
    if (!s.models.empty()) app::check_writable(s.models);

    // Read every record and its stamp first (cfitsio handles stay on this thread), fit in
    // parallel, write in input order: the output does not depend on the thread count.
    JsonlReader reader(s.input, {SourceRecord::schema});
    std::map<std::string, std::unique_ptr<FitsReader>> stamp_files;
    std::vector<Job> jobs;
    SourceRecord source;
    // Field errors from the record's extra fields, placed at the reader's file and line.
    const auto placed = [&](const auto& read) {
        try {
            return read();
        } catch (const Error& e) {
            throw reader.locate(e);
        }
    };
    while (reader.next_record(source)) {
        Job job;
        job.line = reader.line();
        std::string file = s.stamps;
        if (file.empty()) {
            if (!source.extra.contains("stamp_file"))
                throw Error("no stamp_file in the record: give --stamps", reader.name(),
                            reader.line(), "stamp_file");
            file = placed([&] { return required_string(source.extra, "stamp_file"); });
        }
        std::string hdu = source.id;
        if (source.extra.contains("stamp_hdu"))
            hdu = placed([&] { return required_string(source.extra, "stamp_hdu"); });
        auto& fits = stamp_files[file];
        if (!fits) fits = std::make_unique<FitsReader>(file);
        job.stamp = read_stamp(*fits, hdu);
        if (options.given("noise-correlation"))
            job.noise_correlation = s.noise_correlation;
        else if (!s.ignore_correlation && source.extra.contains("noise_correlation"))
            job.noise_correlation = std::max(1.0, placed([&] {
                return required_double(source.extra, "noise_correlation");
            }));
        job.source = source;
        jobs.push_back(std::move(job));
    }
    log.info(jobs.size(), " stamps read in ", log.elapsed(), " s");

    std::vector<Outcome> outcomes(jobs.size());
    std::atomic<std::size_t> next{0};
    auto worker = [&] {
        for (std::size_t k = next++; k < jobs.size(); k = next++) {
            const Job& job = jobs[k];
            Outcome& out = outcomes[k];
            try {
                DecomposeOptions fit = s.fit;
                fit.noise_correlation = job.noise_correlation;
                const double pixel_scale = job.source.extra.value("pixel_scale", 0.0);
                const double zero_point = job.source.extra.value("zero_point", 0.0);
                if (!(pixel_scale > 0.0))
                    throw Error("no pixel_scale in the record", "", 0, "pixel_scale");
                MaskArray mask = (job.stamp.mask != 0.0).cast<std::uint8_t>();
                const double x = job.source.x - (job.stamp.x0 - 1);
                const double y = job.source.y - (job.stamp.y0 - 1);
                const double beta = std::max(job.source.a.value_or(1.0), 0.5);
                out.decomposition = decompose(job.stamp.image, job.stamp.weight, &mask, x, y,
                                              beta, fit);
                out.record = shapelet_record(job.source, *out.decomposition, job.stamp,
                                             pixel_scale, zero_point);
            } catch (const Error& e) {
                out.error = e.message();
            }
        }
    };
    const int threads = std::max(1, std::min<int>(options.common().threads, int(jobs.size())));
    std::vector<std::thread> pool;
    for (int t = 1; t < threads; ++t) pool.emplace_back(worker);
    worker();
    for (auto& t : pool) t.join();

    std::unique_ptr<FitsWriter> models;
    if (!s.models.empty()) models = std::make_unique<FitsWriter>(s.models, "shapesim-decompose");
    const std::set<std::string> wanted = split_ids(s.ids);
    JsonlWriter out(std::cout, "-");
    long converged = 0, failed = 0;
    for (std::size_t k = 0; k < jobs.size(); ++k) {
        const Job& job = jobs[k];
        const Outcome& o = outcomes[k];
        if (!o.record) {
            // A stamp no fit can use (all masked, too small): said on stderr and counted; the
            // run goes on, since one bad stamp must not cost a catalogue.
            ++failed;
            log.warn("object ", job.source.id, " (", reader.name(), ":", job.line,
                     "): ", o.error);
            continue;
        }
        if (std::find(o.record->flags.begin(), o.record->flags.end(), "converged") !=
            o.record->flags.end())
            ++converged;
        out.write(o.record->to_json());
        log.verbose("object ", job.source.id, ": n_max ", o.record->n_max, " chi2r ",
                    *o.record->chi2r, " (", o.decomposition->stop, ")");
        if (models && (wanted.empty() || wanted.count(job.source.id))) {
            const ShapeletFit& fit = o.decomposition->fit;
            const std::vector<FitsKeyword> where{FitsKeyword("LTV1", 1 - job.stamp.x0),
                                                 FitsKeyword("LTV2", 1 - job.stamp.y0)};
            models->write_image(job.stamp.image, {job.source.id + ".data", -32, {}, {}, where, {}});
            models->write_image(fit.model_image,
                                {job.source.id + ".model", -32, {}, {}, where, {}});
            models->write_image(fit.residual,
                                {job.source.id + ".residual", -32, {}, {}, where, {}});
        }
    }
    if (models) models->commit();
    log.info(out.count(), " models (", converged, " converged with chi2_r <= ",
             s.fit.chi2_target, "), ", failed, " stamps not fitted, in ", log.elapsed(), " s");
    return 0;
}

}  // namespace

int main(int argc, char** argv) { return app::run_main(argc, argv, "shapesim-decompose", run); }
