#include "shapesim/render.hpp"

#include "shapesim/basis1d.hpp"
#include "shapesim/error.hpp"
#include "shapesim/polar.hpp"

#include <algorithm>
#include <limits>

namespace shapesim {

PixelWindow PixelWindow::clipped_to(int image_nx, int image_ny) const {
    PixelWindow w;
    w.column0 = std::max(column0, 0);
    w.row0 = std::max(row0, 0);
    w.nx = std::min(column0 + nx, image_nx) - w.column0;
    w.ny = std::min(row0 + ny, image_ny) - w.row0;
    if (w.nx < 0) w.nx = 0;
    if (w.ny < 0) w.ny = 0;
    return w;
}

namespace {

// A (rows × cols) matrix over `buffer`, grown (never shrunk) to hold it.
Eigen::Map<Eigen::MatrixXd> grown(std::vector<double>& buffer, Eigen::Index rows, Eigen::Index cols) {
    if (buffer.size() < std::size_t(rows * cols)) buffer.resize(std::size_t(rows * cols));
    return Eigen::Map<Eigen::MatrixXd>(buffer.data(), rows, cols);
}

// The model integrated over the ny × nx pixels whose first pixel centre lies (dx0, dy0)
// pixels from the model centre: block(j, i) = Σ_{n2} Φ_y(n2, j) Σ_{n1} b(n1, n2) Φ_x(n1, i),
// column-major, in the workspace.
Eigen::Map<Eigen::MatrixXd> pixel_block(const CartesianModel& model, double dx0, double dy0,
                                        int nx, int ny, RenderWorkspace& ws) {
    const int n = model.n_max + 1;
    auto phi_x = grown(ws.phi_x, n, nx);
    auto phi_y = grown(ws.phi_y, n, ny);
    pixel_basis_1d(model.n_max, model.beta_pix, dx0, nx, phi_x, grown(ws.edges, n, nx + 1));
    pixel_basis_1d(model.n_max, model.beta_pix, dy0, ny, phi_y, grown(ws.edges, n, ny + 1));
    auto partial = grown(ws.partial, n, nx);
    partial.noalias() = model.b.transpose() * phi_x;
    auto block = grown(ws.block, ny, nx);
    block.noalias() = phi_y.transpose() * partial;
    return block;
}

}  // namespace

void add_to_image(const CartesianModel& model, ImageArray& image, const PixelWindow& window,
                  RenderWorkspace& ws) {
    const PixelWindow w = window.clipped_to(int(image.cols()), int(image.rows()));
    if (w.empty()) return;
    // Offsets of the window's first pixel centre from the model centre, in pixels.
    const double dx0 = fits_x_of_column(w.column0) - model.x;
    const double dy0 = fits_y_of_row(w.row0) - model.y;
    image.block(w.row0, w.column0, w.ny, w.nx) += pixel_block(model, dx0, dy0, w.nx, w.ny, ws).array();
}

void render_window(const CartesianModel& model, const PixelWindow& window,
                   std::vector<double>& out, RenderWorkspace& ws) {
    require(window.nx >= 0 && window.ny >= 0, "render_window: negative size");
    out.resize(std::size_t(window.nx) * std::size_t(window.ny));
    if (window.empty()) return;
    const auto block = pixel_block(model, fits_x_of_column(window.column0) - model.x,
                                   fits_y_of_row(window.row0) - model.y, window.nx, window.ny, ws);
    Eigen::Map<ImageArray>(out.data(), window.ny, window.nx) = block.array();
}

void add_to_image(const CartesianModel& model, ImageArray& image, const PixelWindow& window) {
    RenderWorkspace ws;
    add_to_image(model, image, window, ws);
}

ImageArray render_stamp(const CartesianModel& model, int nx, int ny) {
    ImageArray image = ImageArray::Zero(ny, nx);
    add_to_image(model, image, PixelWindow{0, 0, nx, ny});
    return image;
}

ImageArray render_stamp(const ShapeletModel& model, int nx, int ny) {
    return render_stamp(to_cartesian(model), nx, ny);
}

PixelHoles pixel_holes(const CartesianModel& model) {
    if (model.n_max == 0) return {};  // a Gaussian of positive flux
    const int half = int(std::ceil(model.beta_pix * (std::sqrt(2.0 * model.n_max + 1.0) + 2.0)));
    const int side = 2 * half + 1;
    CartesianModel m = model;
    m.x = m.y = half + 1.0;
    const ImageArray image = render_stamp(m, side, side);
    const double peak = image.maxCoeff(), total = image.sum();
    constexpr double inf = std::numeric_limits<double>::infinity();
    if (!(peak > 0.0) || !(total > 0.0)) return {inf, inf};
    return {std::max(0.0, -image.minCoeff()) / peak, -image.cwiseMin(0.0).sum() / total};
}

double hole_depth(const ShapeletModel& model) {
    ShapeletModel m = model;
    m.beta_pix = 3.0;
    return pixel_holes(to_cartesian(m)).depth;
}

}  // namespace shapesim
