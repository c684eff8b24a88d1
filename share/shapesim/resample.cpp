#include "shapesim/resample.hpp"

#include "shapesim/error.hpp"

#include <algorithm>
#include <cmath>
#include <string>

namespace shapesim {

Eigen::MatrixXd overlap_matrix(int outputs, double first_centre, double spacing, double width,
                               int inputs) {
    require(outputs >= 0 && inputs >= 0, "overlap_matrix: sizes must be >= 0");
    Eigen::MatrixXd w = Eigen::MatrixXd::Zero(outputs, inputs);
    for (int k = 0; k < outputs; ++k) {
        const double lo = first_centre + k * spacing - 0.5 * width;
        const double hi = lo + width;
        // Input pixels that can touch [lo, hi]; clamp in double before converting to int.
        const double q0 = std::max(0.0, std::floor(lo + 0.5));
        const double q1 = std::min(double(inputs - 1), std::floor(hi + 0.5));
        if (!(q0 <= q1)) continue;  // no overlap (or NaN)
        for (int p = int(q0); p <= int(q1); ++p)
            w(k, p) = std::max(0.0, std::min(hi, p + 0.5) - std::max(lo, p - 0.5));
    }
    return w;
}

ImageArray box_convolve(const ImageArray& image, double width) {
    if (!(width > 0.0) || !std::isfinite(width)) throw Error("box width must be > 0 pixels");
    // Pad by the box's half width so no flux leaves the array; the centre stays at the
    // same offset (pad pixels) from the array origin on both axes.
    const int pad = int(std::ceil(0.5 * width));
    const int nx = int(image.cols()) + 2 * pad, ny = int(image.rows()) + 2 * pad;
    // Output pixel k of the padded array sits at input coordinate k − pad; mean over the box.
    const Eigen::MatrixXd wx = overlap_matrix(nx, -pad, 1.0, width, int(image.cols())) / width;
    const Eigen::MatrixXd wy = overlap_matrix(ny, -pad, 1.0, width, int(image.rows())) / width;
    return (wy * image.matrix() * wx.transpose()).array();
}

ImageArray resample_pixel_integrated(const ImageArray& fine, double fine_scale,
                                     double coarse_scale, PixelPosition fine_point, int out_nx,
                                     int out_ny, PixelPosition out_point) {
    if (fine.size() == 0) throw Error("resample: the fine image is empty");
    if (!(fine_scale > 0.0) || !std::isfinite(fine_scale) || !(coarse_scale > 0.0) ||
        !std::isfinite(coarse_scale))
        throw Error("resample: pixel scales must be finite and > 0");
    if (out_nx <= 0 || out_ny <= 0)
        throw Error("resample: output size must be > 0, got " + std::to_string(out_nx) + "x" +
                    std::to_string(out_ny));
    if (!std::isfinite(fine_point.x) || !std::isfinite(fine_point.y) ||
        !std::isfinite(out_point.x) || !std::isfinite(out_point.y))
        throw Error("resample: reference points must be finite");
    const double ratio = coarse_scale / fine_scale;  // fine pixels per output pixel
    // Output pixel k (0-based) is centred at FITS k + 1, i.e. (k + 1 − out_point)·ratio fine
    // pixels from fine_point, i.e. at 0-based fine index fine_point − 1 + (k + 1 − out)·ratio.
    const Eigen::MatrixXd wx = overlap_matrix(
        out_nx, fine_point.x - 1.0 + (1.0 - out_point.x) * ratio, ratio, ratio, int(fine.cols()));
    const Eigen::MatrixXd wy = overlap_matrix(
        out_ny, fine_point.y - 1.0 + (1.0 - out_point.y) * ratio, ratio, ratio, int(fine.rows()));
    // Overlap lengths are in fine pixels, so W_y(k,q)·W_x(l,p) is the fraction of fine pixel
    // (q, p) inside output pixel (k, l).
    return (wy * fine.matrix() * wx.transpose()).array();
}

PixelPosition flux_centroid(const ImageArray& image) {
    if (image.size() == 0) throw Error("centroid: the image is empty");
    if (!image.allFinite()) throw Error("centroid: the image has NaN or infinite pixels");
    const double total = image.sum();
    if (!(total > 0.0)) throw Error("centroid: the image has no positive flux");
    const Eigen::VectorXd col_sums = image.colwise().sum().transpose().matrix();  // along x
    const Eigen::VectorXd row_sums = image.rowwise().sum().matrix();               // along y
    double sx = 0.0, sy = 0.0;
    for (Eigen::Index i = 0; i < col_sums.size(); ++i) sx += fits_x_of_column(int(i)) * col_sums(i);
    for (Eigen::Index j = 0; j < row_sums.size(); ++j) sy += fits_y_of_row(int(j)) * row_sums(j);
    return {sx / total, sy / total};
}

}  // namespace shapesim
