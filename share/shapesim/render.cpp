#include "shapesim/render.hpp"

#include "shapesim/basis1d.hpp"
#include "shapesim/error.hpp"
#include "shapesim/lane_math.hpp"
#include "shapesim/polar.hpp"

#include <algorithm>
#include <cstring>
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
Eigen::Map<Eigen::MatrixXd> grown(std::vector<double>& buffer, Eigen::Index rows,
                                  Eigen::Index cols) {
    if (buffer.size() < std::size_t(rows * cols)) buffer.resize(std::size_t(rows * cols));
    return Eigen::Map<Eigen::MatrixXd>(buffer.data(), rows, cols);
}

// out(r, ·) = Σ_{k < ends[r]} a[k + r·n] · rows(k, ·) for r < count: each output row a sum of
// rows (row k at rows + k·width) weighted down a column of the column-major a. Every element is
// the sum in order of k, from 0, whether in a lane or not, so any lane width (AVX2 or SSE) gives
// the same bits. Four output rows × four pixels are summed in registers, sharing each load.
__attribute__((target_clones("avx2", "default"))) void weighted_rows(
    const double* a, int n, const int* ends, int count, const double* rows, int width,
    double* out) {
    using lane::Doubles4;
    const int lanes_end = width - width % 4;
    auto tail = [&](int r) {  // the last width % 4 pixels of output row r, one at a time
        const double* ar = a + std::size_t(r) * std::size_t(n);
        for (int c = lanes_end; c < width; ++c) {
            double sum = 0.0;
            for (int k = 0; k < ends[r]; ++k)
                sum += ar[k] * rows[std::size_t(k) * std::size_t(width) + std::size_t(c)];
            out[std::size_t(r) * std::size_t(width) + std::size_t(c)] = sum;
        }
    };
    int r = 0;
    for (; r + 4 <= count; r += 4) {
        const double* w[4];
        for (int q = 0; q < 4; ++q) w[q] = a + std::size_t(r + q) * std::size_t(n);
        const int shared =
            std::min(std::min(ends[r], ends[r + 1]), std::min(ends[r + 2], ends[r + 3]));
        for (int c = 0; c < lanes_end; c += 4) {
            Doubles4 sum[4] = {};
            const double* column = rows + c;
            for (int k = 0; k < shared; ++k) {
                Doubles4 v;
                std::memcpy(&v, column + std::size_t(k) * std::size_t(width), sizeof v);
                sum[0] += w[0][k] * v;
                sum[1] += w[1][k] * v;
                sum[2] += w[2][k] * v;
                sum[3] += w[3][k] * v;
            }
            for (int q = 0; q < 4; ++q) {
                for (int k = shared; k < ends[r + q]; ++k) {
                    Doubles4 v;
                    std::memcpy(&v, column + std::size_t(k) * std::size_t(width), sizeof v);
                    sum[q] += w[q][k] * v;
                }
                std::memcpy(out + std::size_t(r + q) * std::size_t(width) + std::size_t(c),
                            &sum[q], sizeof sum[q]);
            }
        }
        for (int q = 0; q < 4; ++q) tail(r + q);
    }
    for (; r < count; ++r) {
        const double* w = a + std::size_t(r) * std::size_t(n);
        for (int c = 0; c < lanes_end; c += 4) {
            Doubles4 sum = {};
            for (int k = 0; k < ends[r]; ++k) {
                Doubles4 v;
                std::memcpy(&v, rows + std::size_t(k) * std::size_t(width) + std::size_t(c),
                            sizeof v);
                sum += w[k] * v;
            }
            std::memcpy(out + std::size_t(r) * std::size_t(width) + std::size_t(c), &sum,
                        sizeof sum);
        }
        tail(r);
    }
}

// The model integrated over the ny × nx pixels whose first pixel centre lies (dx0, dy0)
// pixels from the model centre: block(j, i) = Σ_{n2} Φ_y(n2, j) Σ_{n1} b(n1, n2) Φ_x(n1, i),
// row-major in the workspace. The inner sums skip b's trailing zeros (n1 + n2 > n_max).
double* pixel_block(const CartesianModel& model, double dx0, double dy0, int nx, int ny,
                    RenderWorkspace& ws) {
    const int n = model.n_max + 1;
    auto phi_x = grown(ws.phi_x, n, nx);
    auto phi_y = grown(ws.phi_y, n, ny);
    pixel_basis_1d(model.n_max, model.beta_pix, dx0, nx, phi_x, grown(ws.edges, n, nx + 1));
    pixel_basis_1d(model.n_max, model.beta_pix, dy0, ny, phi_y, grown(ws.edges, n, ny + 1));
    // Φ_x's rows contiguous (row-major n × nx), for the sums along pixels.
    auto phi_x_rows = grown(ws.edges, nx, n);
    phi_x_rows = phi_x.transpose();
    ws.ends.resize(std::size_t(n));
    for (int n2 = 0; n2 < n; ++n2) {
        int end = n;
        while (end > 0 && model.b(end - 1, n2) == 0.0) --end;
        ws.ends[std::size_t(n2)] = end;
    }
    auto partial = grown(ws.partial, nx, n);  // row-major n × nx: partial(n2, i)
    weighted_rows(model.b.data(), n, ws.ends.data(), n, phi_x_rows.data(), nx, partial.data());
    ws.ends.assign(std::size_t(ny), n);
    auto block = grown(ws.block, nx, ny);  // row-major ny × nx
    weighted_rows(phi_y.data(), n, ws.ends.data(), ny, partial.data(), nx, block.data());
    return block.data();
}

}  // namespace

void add_to_image(const CartesianModel& model, ImageArray& image, const PixelWindow& window,
                  RenderWorkspace& ws) {
    const PixelWindow w = window.clipped_to(int(image.cols()), int(image.rows()));
    if (w.empty()) return;
    // Offsets of the window's first pixel centre from the model centre, in pixels.
    const double dx0 = fits_x_of_column(w.column0) - model.x;
    const double dy0 = fits_y_of_row(w.row0) - model.y;
    const double* block = pixel_block(model, dx0, dy0, w.nx, w.ny, ws);
    image.block(w.row0, w.column0, w.ny, w.nx) += Eigen::Map<const ImageArray>(block, w.ny, w.nx);
}

double* render_window(const CartesianModel& model, const PixelWindow& window,
                      RenderWorkspace& ws) {
    require(window.nx >= 0 && window.ny >= 0, "render_window: negative size");
    if (window.empty()) return ws.block.data();
    return pixel_block(model, fits_x_of_column(window.column0) - model.x,
                       fits_y_of_row(window.row0) - model.y, window.nx, window.ny, ws);
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
