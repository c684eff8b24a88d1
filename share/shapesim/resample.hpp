// Pixel resampling: box convolution and flux-conserving re-pixelisation of a finely sampled
// image (an oversampled PSF) onto a coarser grid; the one home of this maths. image(j, i) is
// the pixel centred at FITS (i + 1, j + 1), its value the flux over it; a fine image is
// piecewise constant. Separable: out = W_y · image · W_xᵀ. Resampling blurs by a variance
// ≤ h²/4 (h the fine pixel in coarse pixels), 0 when the edges align.
// Derivation: docs/algorithms.md#resampling
#pragma once

#include "shapesim/geometry.hpp"  // PixelPosition
#include "shapesim/image.hpp"

#include <Eigen/Dense>

namespace shapesim {

/// The 1D overlap matrix W (outputs × inputs) between output cells and input pixels, in the
/// input's 0-based index coordinate (input pixel p covers [p − ½, p + ½]): output cell k
/// spans [c_k − width/2, c_k + width/2] with c_k = first_centre + k·spacing, and W(k, p) is
/// the length of its overlap with input pixel p (0 … 1). Row sums are the part of the cell
/// that lies over the input.
Eigen::MatrixXd overlap_matrix(int outputs, double first_centre, double spacing, double width,
                               int inputs);

/// `image` convolved with a square box `width_pixels` wide (separable, flux-conserving: each
/// pixel is spread uniformly over the box). The result is padded by pad = ⌈width/2⌉ pixels on
/// every side, so no flux is lost and a point at FITS (x, y) of the input sits at
/// (x + pad, y + pad) of the output. On the pixel lattice the box is the discrete kernel
/// k_p = |[p − ½, p + ½] ∩ [−w/2, w/2]| / w, whose variance is
///   V(w) = (2/w)·[K(K+1)(2K+1)/6 + r(K+1)²],  K = ⌊w/2 − ½⌋,  r = w/2 − K − ½
/// per axis ((w² − 1)/12 for odd and (w² + 2)/12 for even integer w; in general
/// w²/12 − 1/12 ≤ V(w) < w²/12 + 0.175, the maximum near w = 1.82).
/// For PSF images that lack the detector pixel or a drizzle drop (TinyTim's subsampled PSFs
/// omit both). Error unless width is finite and > 0.
ImageArray box_convolve(const ImageArray& image, double width_pixels);

/// Flux-conserving re-pixelisation of `fine` (pixels `fine_scale` wide, e.g. arcsec) onto an
/// out_nx × out_ny grid of pixels `coarse_scale` wide: each output pixel is the integral of
/// the piecewise-constant fine image over its area. The fine image's point `fine_point` (its
/// own FITS coordinates) lands on `out_point` (the output's FITS coordinates). Flux that
/// falls outside the output is dropped; everything inside is conserved exactly (to
/// rounding). Either scale may be the larger (an output finer than the input just splits
/// pixels). Error unless both scales are finite and > 0, the sizes are > 0 and `fine` is
/// not empty. Cost O(out_ny · fine_ny · fine_nx + out_ny · fine_nx · out_nx).
ImageArray resample_pixel_integrated(const ImageArray& fine, double fine_scale,
                                     double coarse_scale, PixelPosition fine_point, int out_nx,
                                     int out_ny, PixelPosition out_point);

/// Flux-weighted centroid Σ x·I / Σ I in FITS coordinates (pixel values at pixel centres).
/// Error when the image is empty, has non-finite pixels or Σ I ≤ 0.
PixelPosition flux_centroid(const ImageArray& image);

}  // namespace shapesim
