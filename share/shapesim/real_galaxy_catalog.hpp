// GalSim's RealGalaxyCatalog: the format in which the COSMOS training samples (tens of
// thousands of HST ACS galaxies) are distributed (GalSim's real.py). A FITS binary table, one
// row per galaxy: IDENT, MAG, WEIGHT, the stamp's and the PSF's files and HDUs, PIXEL_SCALE,
// NOISE_MEAN, NOISE_VARIANCE. real_galaxy_job() turns a row into a decomposition job through
// the galaxy's own PSF. Columns and defaults: docs/algorithms.md#galsim-realgalaxycatalog
#pragma once

#include "shapesim/decompose_job.hpp"
#include "shapesim/psf.hpp"

#include <optional>
#include <string>
#include <vector>

namespace shapesim {

/// One row of a RealGalaxyCatalog.
struct RealGalaxy {
    std::string ident;      ///< IDENT (an integer column written as its digits)
    long row = 0;           ///< 1-based table row
    double mag = 0.0;       ///< MAG
    std::string band;       ///< BAND (empty when absent)
    double weight = 1.0;    ///< WEIGHT
    std::optional<double> ra, dec;  ///< degrees
    std::string image;      ///< cfitsio path of the stamp: `folder/GAL_FILENAME[GAL_HDU]`
    std::string psf;        ///< cfitsio path of the PSF image: `folder/PSF_FILENAME[PSF_HDU]`
    /// The catalogue's PSF file is absent (absent_psf_files): `psf` is a stated substitute.
    bool psf_substituted = false;
    double pixel_scale = 0.0;     ///< arcsec per pixel, > 0
    double noise_mean = 0.0;      ///< image units
    double noise_variance = 0.0;  ///< image units², > 0
};

/// The rows of the RealGalaxyCatalog `path` (its first table HDU, or the HDU `path` names).
/// File names are taken relative to `image_folder` (empty: the catalogue's folder). Error
/// naming the table, the row (as the line) and the column for a missing required column or a
/// value out of range (a non-finite MAG, PIXEL_SCALE or NOISE_VARIANCE ≤ 0, a negative or
/// fractional HDU, an empty file name, a negative WEIGHT).
std::vector<RealGalaxy> read_real_galaxy_catalog(const std::string& path,
                                                 const std::string& image_folder = {});

/// The galaxies (indices) whose PSF file, `psf` before any `[HDU]`, is absent, in order; each
/// file is looked up once. The COSMOS samples are often copied without their PSF files: a caller
/// then states a substitute (psf_substituted) or refuses the catalogue.
std::vector<std::size_t> absent_psf_files(const std::vector<RealGalaxy>& galaxies);

/// The PSF image of `galaxy` (its sky removed: read_psf_image()), read on the caller's thread.
/// Errors name the catalogue, the row and the file's column.
PsfImage read_real_galaxy_psf(const RealGalaxy& galaxy, const std::string& catalogue);

/// The shapelet model of a PSF image at the galaxy's pixel scale `pixel_scale`, a unit-flux
/// model in pixels centred at (0, 0), with the fit's quality (psf.hpp). Error when the image
/// is unusable.
PsfModel real_galaxy_psf(const PsfImage& image, double pixel_scale, int stamp_pixels,
                         const PsfFitOptions& options = {});

/// `galaxy`'s decomposition job without its PSF (set job.psf from real_galaxy_psf()): its
/// stamp (noise mean removed, weight 1/NOISE_VARIANCE; NaN and ±Inf pixels weigh nothing),
/// its neighbours masked (see the .cpp), a source record from the galaxy's detection (the
/// stamp's centre and no a when nothing is detected). `catalogue` is written as the record's
/// "image". Error naming the catalogue, row and stamp when the stamp cannot be read or holds
/// no finite pixel.
/// `gain` (e⁻ per image unit, 0: none) adds the galaxy's photon noise to the weights
/// (add_source_noise); the job's noise correlation is the stamp's sky blocks' (detect.hpp).
DecomposeJob real_galaxy_job(const RealGalaxy& galaxy, const std::string& catalogue,
                             double gain = 0.0);

}  // namespace shapesim
