// Pixel arrays. One convention everywhere in the library:
//   image(j, i) is the pixel centred at FITS coordinates (x, y) = (i + 1, j + 1),
// i.e. rows run along y (NAXIS2) and columns along x (NAXIS1), row-major like FITS on disk.
// The shift between 1-based FITS/catalogue positions and 0-based indices happens only here
// and in fits_io.
#pragma once

#include <Eigen/Dense>

namespace shapesim {

/// A 2D image: ny rows × nx columns, row-major (FITS order). Row j is y = j + 1.
using ImageArray = Eigen::Array<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

/// FITS x of column i (0-based) and its inverse; same for rows and y.
constexpr double fits_x_of_column(int i) { return i + 1.0; }
constexpr double fits_y_of_row(int j) { return j + 1.0; }

}  // namespace shapesim
