// The rendering kernel: the exact pixel-integrated image of a shapelet model.
//
// A Cartesian model is separable, so its pixel-integrated image is a matrix product
// (DESIGN §3):   P = Φ_yᵀ · bᵀ · Φ_x,   Φ_x(n1, i) = ∫_{pixel i} B_{n1}(x − x_c) dx,
// with Φ from `pixel_basis_1d`. Cost O(n_max · nx · ny) per stamp (plus O(n_max²·nx)), against
// O(n_max² · nx · ny) for evaluating every basis function in every pixel.
// Pixel values are integrals over the unit pixel (image units per pixel, DESIGN §2).
#pragma once

#include "shapesim/image.hpp"
#include "shapesim/model.hpp"

#include <Eigen/Dense>

#include <vector>

namespace shapesim {

/// A rectangle of pixels, 0-based column/row of its first pixel and its size.
struct PixelWindow {
    int column0 = 0, row0 = 0;
    int nx = 0, ny = 0;
    bool empty() const { return nx <= 0 || ny <= 0; }
    /// The part of this window inside an image of nx × ny pixels.
    PixelWindow clipped_to(int image_nx, int image_ny) const;
};

/// Reusable buffers so that rendering many models does not allocate in the hot loop. They only
/// grow: Eigen's resize reallocates at every new size, and large blocks go back to the system
/// (munmap), whose TLB shootdowns stall every other thread of the process — painting on two
/// threads was slower than on one (issue 16).
struct RenderWorkspace {
    std::vector<double> phi_x, phi_y, edges, partial, block;
    std::vector<int> ends;  ///< per output row, how many terms of its sum are not zero
};

/// The model integrated over `window` of the image its centre refers to (0-based columns and
/// rows, not clipped: a window may overhang the image), row-major ny × nx in the workspace
/// (valid, and the caller's to change, until its next use). The same numbers add_to_image adds
/// there.
double* render_window(const CartesianModel& model, const PixelWindow& window,
                      RenderWorkspace& workspace);

/// Add the pixel-integrated model into `window` of `image` (clipped to the image). The model's
/// centre is in the image's own FITS pixel coordinates.
void add_to_image(const CartesianModel& model, ImageArray& image, const PixelWindow& window,
                  RenderWorkspace& workspace);
void add_to_image(const CartesianModel& model, ImageArray& image, const PixelWindow& window);

/// A new nx × ny stamp holding the pixel-integrated model; the model centre is in the stamp's
/// FITS coordinates (first pixel centred at (1, 1)).
ImageArray render_stamp(const CartesianModel& model, int nx, int ny);
ImageArray render_stamp(const ShapeletModel& model, int nx, int ny);

/// How far a model dips below zero, as a fraction of its peak: max(0, −min)/max of the model
/// pixel-integrated with β = 3 pixels out to β(√(2n+1) + 2). A galaxy's light is never
/// negative; its model dips where the data's noise or a truncated series ring.
double hole_depth(const ShapeletModel& model);
/// A model's holes as it renders on its own pixels (its β_pix), out to β(√(2n+1) + 2), in the
/// image it describes: `depth` max(0, −min)/max, and `negative_light` the light below zero over
/// the total (a shallow but wide negative ring can hold as much light as the galaxy).
struct PixelHoles {
    double depth = 0.0;
    double negative_light = 0.0;
};
PixelHoles pixel_holes(const CartesianModel& model);

}  // namespace shapesim
