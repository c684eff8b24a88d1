// A minimal end-to-end use of the library (the README's example): read a shapelet record,
// render it pixel-integrated to a FITS file, read the file back, fit it at the record's centre,
// β and n_max, and print the fitted record. stderr gets the round-trip error.
//
//   render_and_fit MODELS.jsonl ID OUT.fits [NOISE_SIGMA SEED] > fitted.jsonl
#include "app/run_main.hpp"
#include "shapesim/error.hpp"
#include "shapesim/fits_io.hpp"
#include "shapesim/jsonl.hpp"
#include "shapesim/lsq.hpp"
#include "shapesim/records.hpp"
#include "shapesim/render.hpp"
#include "shapesim/rng.hpp"

#include <cmath>
#include <iostream>
#include <string>

using namespace shapesim;

namespace {
ShapeletRecord find_record(const std::string& path, const std::string& id) {
    JsonlReader reader(path, {ShapeletRecord::schema});
    Json json;
    while (reader.next(json)) {
        ShapeletRecord record;
        try {
            record = ShapeletRecord::from_json(json);
        } catch (const Error& e) {
            throw reader.locate(e);
        }
        if (record.id == id) return record;
    }
    throw Error("no record with id " + id, path);
}

int run(int argc, const char* const argv[]) {
    if (argc != 4 && argc != 6)
        throw Error("usage: render_and_fit MODELS.jsonl ID OUT.fits [NOISE_SIGMA SEED]");
    const ShapeletRecord record = find_record(argv[1], argv[2]);
    const ShapeletModel truth = record.to_model();

    // Stamp: centred on the model, 2 × 5 β √(n_max+1) on a side.
    const int side = 2 * int(std::ceil(5.0 * truth.beta_pix * std::sqrt(truth.n_max + 1.0))) + 1;
    ShapeletModel placed = truth;
    placed.x = placed.y = (side + 1) / 2.0;
    ImageArray image = render_stamp(placed, side, side);
    double sigma = 0.0;
    if (argc == 6) {  // optional Gaussian noise from a keyed stream: reproducible per seed
        sigma = std::stod(argv[4]);
        RandomStream noise(std::stoull(argv[5]), record.id, "noise");
        for (long p = 0; p < image.size(); ++p) image.data()[p] += sigma * noise.gaussian();
    }
    FitsWriter out(argv[3], "render_and_fit", {FitsKeyword("MODELID", record.id)});
    out.write_image(image, FitsImageSpec{"IMAGE", -64, {}, std::nullopt, {}, {}});
    out.commit();

    const ImageArray back = read_fits_image(std::string(argv[3]) + "[IMAGE]");
    const ImageArray weight = ImageArray::Constant(side, side, sigma > 0 ? 1 / (sigma * sigma) : 1.0);
    const ShapeletFit fit =
        fit_shapelets(back, weight, nullptr, placed.x, placed.y, placed.beta_pix, placed.n_max);
    ShapeletRecord fitted = ShapeletRecord::from_model(fit.model, record.pixel_scale, record.id);
    fitted.chi2r = fit.chi2r;
    JsonlWriter(std::cout, "-").write(fitted.to_json());

    const Eigen::VectorXd a = real_parameters(fit.model), t = real_parameters(placed);
    std::cerr << "render_and_fit: " << record.id << " n_max " << truth.n_max << " stamp " << side
              << "x" << side << " max|a_fit - a_true|/max|a| = "
              << (a - t).cwiseAbs().maxCoeff() / t.cwiseAbs().maxCoeff() << " chi2r "
              << fit.chi2r << "\n";
    return 0;
}
}  // namespace

int main(int argc, char** argv) { return app::run_main(argc, argv, "render_and_fit", run); }
