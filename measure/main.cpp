// shapesim-measure: the morphology diagnostics of every galaxy of an image (paper §5,
// DESIGN §5) as shapesim.morph/1 records. Detection is shapesim-detect's own
// (app/detection_run.hpp), the statistics are measure.hpp / morphometry.hpp.
#include "shapesim/app/detection_run.hpp"
#include "shapesim/app/options.hpp"
#include "shapesim/app/run_main.hpp"
#include "shapesim/error.hpp"
#include "shapesim/jsonl.hpp"
#include "shapesim/measure.hpp"
#include "shapesim/stellarity.hpp"

#include <atomic>
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
    "Example (the shipped HDF-N data):\n"
    "  shapesim-measure hdfn_f814w_v2.fits --weight hdfn_f814w_v2_weight.fits \\\n"
    "      --zero-point 22.08 -j 2 > hdf.morph.jsonl";

int run(int argc, const char* const argv[]) {
    app::ProgramOptions options("shapesim-measure", "[OPTION]... IMAGE", description,
                                app::Common::quiet | app::Common::verbose | app::Common::threads |
                                    app::Common::config | app::Common::print_params);
    app::DetectionSettings detection;
    MeasureOptions measure;
    bool stars = false;
    detection.declare(options);
    using app::in_range;
    options.group("Statistics").add_options()
        ("with-stars", po::bool_switch(&stars), "also measure the stars (kind \"star\")")
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
    if (!options.parse(argc, argv)) return 0;
    const app::Log log("shapesim-measure", options.common().verbosity);

    const app::DetectionRun detected = detection.run(options, log);
    const DetectionResult& field = detected.field;
    struct Job {
        SourceRecord source;
        std::optional<MorphRecord> record;
        std::string error;
    };
    std::vector<Job> jobs;
    for (const Detection& object : field.objects) {
        const CoreFraction core = core_fraction(field, object, detected.locus);
        const double star = stellarity(core, detected.locus);
        if (star > detection.star_threshold && !stars) continue;
        jobs.push_back({source_record(object, core, star, nullptr, detected.context), {}, {}});
    }
    std::atomic<std::size_t> next{0};
    auto worker = [&] {
        for (std::size_t k = next++; k < jobs.size(); k = next++) {
            try {
                const Detection& object = field.objects[std::size_t(std::stoi(jobs[k].source.id) - 1)];
                jobs[k].record = measure_object(field, object, jobs[k].source, measure);
            } catch (const std::exception& e) {
                jobs[k].error = e.what();
            }
        }
    };
    const int threads = std::max(1, std::min<int>(options.common().threads, int(jobs.size())));
    std::vector<std::thread> pool;
    for (int t = 1; t < threads; ++t) pool.emplace_back(worker);
    worker();
    for (auto& t : pool) t.join();

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
             " in ", log.elapsed(), " s");
    return 0;
}

}  // namespace

int main(int argc, char** argv) { return app::run_main(argc, argv, "shapesim-measure", run); }
