// shapesim-decompose's options: their table (groups Input, Bands, Optimiser, PSF mode, Output,
// in --help's order), their checks, and the named inputs they open for the fits (JobReader).
#pragma once

#include "app/options.hpp"
#include "shapesim/decompose.hpp"
#include "shapesim/decompose_job.hpp"
#include "shapesim/psf.hpp"

#include <string>
#include <vector>

namespace shapesim::app {

struct DecomposeSettings {
    std::string stamps, models, ids, stars;
    std::string psf_image, psf, psf_field, reference_band;
    std::string real_galaxy_catalog, real_galaxy_folder, real_galaxy_psf, psf_analytic;
    double psf_tolerance = 0.01;
    int batch = 256;
    double gain = 0.0;
    std::vector<std::string> band_psfs, band_noise_models;
    std::string noise_model;
    bool no_bands = false;
    double psf_pixel_scale = 0.0, pixel_scale = 0.0, psf_residual = 0.01;
    std::vector<double> psf_box;
    int psf_stamp = 41, psf_n_max_cap = 20;
    std::string input = "-";
    bool ignore_correlation = false;
    bool round_lowest = false;
    double noise_correlation = 0.0;
    DecomposeOptions fit;

    /// Add every option of shapesim-decompose to `options`.
    void declare(ProgramOptions& options);
    /// Settle the fit's options (elliptical unless --round-lowest) and check the options
    /// together (po::error, Error); --models is checked writable.
    void check();
    /// Open --stamps, read --psf, --band-psf, --noise-model (into `fit`) and
    /// --band-noise-model, in that order.
    JobReader job_reader(const ProgramOptions& options);

    /// PSF mode: the target pixel scale, --pixel-scale's or that of --like (po::error without
    /// either).
    double psf_target_scale(const ProgramOptions& options) const;
    /// PSF mode: the fit's options (--psf-residual, --psf-n-max-cap).
    PsfFitOptions psf_fit() const;
};

}  // namespace shapesim::app
