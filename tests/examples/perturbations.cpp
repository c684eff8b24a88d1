// perturbations: the paper's negative-flux diagnostic (§4.1) and its Fig. 3 for a morphology
// model from shapesim-smooth.
//
//   perturbations MORPH.json OUT.pgm [DRAWS] [PIXEL_SCALE]
//
// For each λ scale factor k in 0, 1, 2, 4, 8 every smoothing length of the model (built with
// k0 = provenance.options.k, 4 by default; phases included: 15° at k = 4) is scaled by k/k0,
// DRAWS galaxies (default 2000) are drawn as shapesim-sample draws them and rendered
// noise-free at PIXEL_SCALE (default 0.03985″, the HDF's) on a stamp out to model_reach();
// a galaxy "has a hole" when its minimum pixel is below −1% of its peak. Printed per k: the
// fraction with holes among all draws and among those with n_max ≥ 2 (n_max 0 and 1 models
// are positive everywhere), and the mean relative perturbation ‖c' − c‖/‖c‖.
//
// OUT.pgm: one galaxy — the parent of highest n_max whose own model has no hole — in rows of k = 0, 1, 2, 4, 8 and six
// draws each, turned back to the parent's own orientation, one asinh stretch for all, the
// background at 30% grey so negative holes show dark.
#include "app/run_main.hpp"
#include "shapesim/error.hpp"
#include "shapesim/morphology.hpp"
#include "shapesim/render.hpp"
#include "shapesim/transform.hpp"
#include "grey_canvas.hpp"

#include <algorithm>
#include <cmath>
#include <iostream>

using namespace shapesim;

namespace {

Morphology scaled(const Morphology& m, double factor) {
    Morphology out = m;
    out.lambda.phase_deg *= factor;
    out.lambda.beta *= factor;
    out.lambda.mag *= factor;
    for (double& l : out.lambda.coefficient) l *= factor;
    return out;
}

ImageArray render_centred(const ShapeletModel& model, int side) {
    ShapeletModel m = model;
    m.x = m.y = (side + 1) / 2.0;
    return render_stamp(m, side, side);
}

int run(int argc, const char* const argv[]) {
    if (argc < 3 || argc > 5) {
        std::cerr << "usage: perturbations MORPH.json OUT.pgm [DRAWS] [PIXEL_SCALE]\n";
        return 2;
    }
    const Morphology morph = Morphology::read(argv[1]);
    const int draws = argc >= 4 ? std::max(1, std::atoi(argv[3])) : 2000;
    const double scale = argc >= 5 ? std::atof(argv[4]) : 0.03985;
    require(scale > 0.0, "pixel scale must be > 0");
    double k0 = 4.0;
    if (morph.provenance.contains("options") && morph.provenance["options"].contains("k"))
        k0 = morph.provenance["options"]["k"].get<double>();
    require(k0 > 0.0, "the model was built with k = 0: nothing to scale");
    const double zero_point = morph.zero_point.value_or(0.0);
    const double ks[5] = {0.0, 1.0, 2.0, 4.0, 8.0};

    std::cout << "| k | holes, all draws | holes, n_max >= 2 | mean perturbation |\n"
              << "|---|---|---|---|\n";
    for (double k : ks) {
        const Morphology m = scaled(morph, k / k0);
        const std::vector<double> parents = parent_table(m, 99.0);
        long holes = 0, holes_high = 0, high = 0;
        double perturbation = 0.0;
        for (int i = 0; i < draws; ++i) {
            RandomStream stream(1, std::uint64_t(i), "galaxy");
            const DrawnGalaxy g = draw_galaxy(m, parents, stream, scale, zero_point, 99.0);
            const int side = 2 * int(std::ceil(model_reach(g.model.beta_pix, g.model.n_max))) + 1;
            const ImageArray image = render_centred(g.model, std::min(side, 401));
            const bool hole = image.minCoeff() < -0.01 * image.maxCoeff();
            holes += hole;
            if (g.model.n_max >= 2) {
                ++high;
                holes_high += hole;
            }
            perturbation += g.perturbation;
        }
        std::cout << "| " << k << " | " << double(holes) / draws << " | "
                  << (high ? double(holes_high) / double(high) : 0.0) << " (of " << high
                  << ") | " << perturbation / draws << " |\n";
    }

    // Fig. 3: the parent of highest n_max (the brightest of those) whose own model has no hole
    // (else the brightest of highest n_max), perturbed at each k.
    auto has_hole = [&](const MorphologyPoint& p) {
        ShapeletModel m(0.0, 0.0, p.beta / scale, p.n_max);
        m.coeffs = p.shape;
        const int side = 2 * int(std::ceil(model_reach(m.beta_pix, m.n_max))) + 1;
        const ImageArray image = render_centred(m, std::min(side, 401));
        return image.minCoeff() < -0.01 * image.maxCoeff();
    };
    std::size_t best = 0;
    bool best_clean = !has_hole(morph.points[0]);
    for (std::size_t i = 1; i < morph.points.size(); ++i) {
        const auto& p = morph.points[i];
        const auto& b = morph.points[best];
        const bool clean = !has_hole(p);
        if (clean != best_clean) {
            if (clean) {
                best = i;
                best_clean = true;
            }
            continue;
        }
        if (p.n_max > b.n_max || (p.n_max == b.n_max && p.mag < b.mag)) best = i;
    }
    const MorphologyPoint& parent = morph.points[best];
    const double beta_pix = parent.beta / scale;
    const int side = 2 * int(std::ceil(beta_pix * (std::sqrt(parent.n_max + 1.0) + 2.0))) + 1;
    const int columns = 6, gap = 2, zoom = 3;
    std::vector<std::vector<ImageArray>> rows;
    for (double k : ks) {
        Morphology m = scaled(morph, k / k0);
        m.points = {parent};
        const std::vector<double> parents = parent_table(m, 99.0);
        std::vector<ImageArray> row;
        for (int c = 0; c < columns; ++c) {
            RandomStream stream(2, std::uint64_t(c), "galaxy");
            const DrawnGalaxy g = draw_galaxy(m, parents, stream, scale, zero_point, 99.0);
            ShapeletModel back = rotate(g.model, -g.rotation);
            if (g.reflected) back = reflect_x(back);
            row.push_back(render_centred(unalign(back, parent.alignment), side));
        }
        rows.push_back(std::move(row));
    }
    const double peak = rows[0][0].maxCoeff();
    const double soft = peak / 20.0;  // asinh knee
    const double top = std::asinh(peak / soft), bottom = -0.3 / 0.7 * top;
    const int nx = (columns * (side + gap)) * zoom, ny = int(rows.size()) * (side + gap) * zoom;
    examples::GreyCanvas canvas(nx, ny);
    const examples::AsinhStretch stretch{soft, bottom, top};
    for (std::size_t r = 0; r < rows.size(); ++r)
        for (int c = 0; c < columns; ++c)
            canvas.paste(rows[r][std::size_t(c)], c * (side + gap) * zoom,
                         int(r) * (side + gap) * zoom, zoom, stretch);
    canvas.write(argv[2]);
    std::cerr << "perturbations: parent " << parent.id << " (n_max " << parent.n_max << ", mag "
              << parent.mag << ") in rows k = 0, 1, 2, 4, 8\n";
    return 0;
}

}  // namespace

int main(int argc, char** argv) { return app::run_main(argc, argv, "perturbations", run); }
