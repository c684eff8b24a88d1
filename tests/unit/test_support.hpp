// Shared helpers for the unit tests: where the fixtures are, reading the GalSim reference
// models and stamps, and an independent quadrature (composite Gauss–Legendre) for brute force.
#pragma once

#include "shapesim/image.hpp"
#include "shapesim/model.hpp"

#include <functional>
#include <string>
#include <vector>

namespace shapesim::test {

/// Folder of the exact reference fixtures (tests/data/reference in the repository; else
/// $SHAPESIM_DATA/reference; else ../shared/data/reference).
std::string reference_dir();

/// One model of reference/models.jsonl with its id and stamp size.
struct ReferenceModel {
    std::string id;
    ShapeletModel model;
    int nx = 0, ny = 0;
    ImageArray stamp;  ///< the GalSim-rendered stamp from stamps.fits
};
/// All 24 reference models with their stamps (read once, cached).
const std::vector<ReferenceModel>& reference_models();

/// The HDU (1-based, primary = 1) of a FITS file as an image, read with cfitsio directly.
ImageArray read_fits_image(const std::string& path, int hdu);

/// n-point Gauss–Legendre nodes and weights on [−1, 1] (Newton on P_n; independent of the
/// library's Gauss–Hermite code).
void gauss_legendre(int n, std::vector<double>& nodes, std::vector<double>& weights);

/// ∫_a^b f(x) dx by composite Gauss–Legendre: `panels` panels of `order` points each.
double integrate(const std::function<double(double)>& f, double a, double b, int panels = 1,
                 int order = 20);

/// A model with random coefficients (galaxy-like when `galaxy`), deterministic in `seed`.
ShapeletModel random_model(int n_max, double beta_pix, double x, double y, unsigned seed,
                           bool galaxy = true);

}  // namespace shapesim::test
