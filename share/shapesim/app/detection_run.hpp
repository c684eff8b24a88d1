// Detection as shapesim-detect runs it, for every program that detects (shapesim-detect,
// shapesim-measure): the same options, the same defaults, the same steps — read the image,
// its WCS, zero point and noise map; build the point-source locus; detect_sources().
#pragma once

#include "shapesim/app/log.hpp"
#include "shapesim/app/options.hpp"
#include "shapesim/detect.hpp"
#include "shapesim/noise.hpp"
#include "shapesim/sources.hpp"
#include "shapesim/stamps.hpp"
#include "shapesim/stellarity.hpp"

#include <string>
#include <vector>

namespace shapesim::app {

/// The detected field and what its records need.
struct DetectionRun {
    ImageArray image;        ///< the input image as read
    SourceContext context;   ///< geometry, zero point, noise correlation (stamps left empty)
    PointSourceLocus locus;  ///< the PSF's point-source locus for the stellarity
    /// Where the locus came from, for the run's summary line: the PSF file, or the assumed
    /// Gaussian (an assumption a user should see: it can call a star a galaxy).
    std::string locus_note;
    DetectionResult field;   ///< detections, segmentation, background-subtracted image
};

struct DetectionSettings {
    std::string image, weight, weight_type = "weight", filter = "default", filter_mode = "conv";
    std::string psf_image, psf_model, psf_analytic;
    double pixel_scale = 0.0, ra = 0.0, dec = 0.0, zero_point = 0.0;
    double psf_fwhm = 0.15, psf_pixel_scale = 0.0, star_threshold = 0.97;
    double saturation = 0.0;  ///< --saturation (0: none; not given: the header's SATURATE)
    std::vector<double> psf_box;
    bool no_clean = false, no_rescale = false;
    DetectionOptions detection;

    /// The positional IMAGE (required unless `image_required` is false) and the groups
    /// "Input", "Detection (SExtractor parameters)" and "Stars".
    void declare(ProgramOptions& options, bool image_required = true);
    /// Check the values and run the detection (Error / po::error on bad input).
    DetectionRun run(const ProgramOptions& options, const Log& log);
};

/// The stamps' options (--stamp-factor, --stamp-offset, --stamp-sky-margin, --stamp-max-side,
/// --border-width), added in that order to the group `add` adds to.
void declare_stamp_options(po::options_description_easy_init& add, StampOptions& stamp);
/// The sky noise measurement's options (--noise-radius, --noise-grow, --noise-mask-snr).
void declare_sky_noise_options(po::options_description_easy_init& add, SkyNoiseOptions& noise);

}  // namespace shapesim::app
