// Colours of real and simulated fields compared (issue 17): catalogues of shapesim-detect
// --bands (dual-image mode: every band measured in the detection's apertures), the colour
// of each pair of adjacent bands and its internal gradient, real against simulated.
//
//  - colour of bands (b, b+1): m_b − m_{b+1} from the forced AUTO fluxes, for galaxies of the
//    detection band brighter than a magnitude limit with both fluxes > 0 (the same cut on both
//    sides, so the distributions compare);
//  - colour gradient: the inner circle's colour (bands.hpp inner_radius(), ≈ the half-light
//    radius) less the outer colour (the AUTO flux outside it), where all four fluxes are > 0:
//    negative for a red core in a bluer disc;
//  - per catalogue and colour: the number of galaxies, the mean colour with its bootstrap
//    error, and the two-sample KS test of colours and of gradients against the first
//    catalogue; the colour–magnitude relation as the median colour per magnitude bin.
#pragma once

#include "shapesim/records.hpp"
#include "shapesim/statistics.hpp"

#include <iosfwd>
#include <string>
#include <vector>

namespace shapesim {

/// A catalogue's per-band photometry (its records' `bands` entries, in their order).
struct ColourCatalogue {
    std::string name;
    std::vector<std::string> bands;
    struct Galaxy {
        double mag = 0.0;                      ///< detection band
        std::vector<double> flux, inner, error;  ///< per band: AUTO, inner circle, AUTO's σ
    };
    std::vector<Galaxy> galaxies;  ///< those with a magnitude (stars left out)

    /// From source records of shapesim-detect --bands; Error naming the record when its bands
    /// differ from the first record's (or it has none).
    static ColourCatalogue from_records(std::string name, const std::vector<SourceRecord>& records);
    /// The colours m_b − m_{b+1} (and their magnitudes) of the galaxies with mag ≤ `mag_limit`.
    std::vector<double> colours(std::size_t b, double mag_limit,
                                std::vector<double>* mags = nullptr) const;
    /// The gradients (inner − outer colour) of bands (b, b+1) of those galaxies.
    std::vector<double> gradients(std::size_t b, double mag_limit) const;
};

/// One adjacent colour of one catalogue against the reference (the first).
struct ColourComparison {
    std::string colour;  ///< "f606w-f775w"
    std::size_t n = 0, n_gradient = 0;
    double mean = 0.0, mean_error = 0.0;  ///< bootstrap error of the mean
    double gradient_median = 0.0;
    KsResult colour_ks, gradient_ks;      ///< against the reference (itself: D 0, p 1)
    /// (mean − reference mean) / √(σ² + σ_ref²): how far the means differ in their errors.
    double mean_offset_sigmas = 0.0;
};

/// Every adjacent colour of every catalogue against the first. Error unless all catalogues
/// have the same bands, at least two.
std::vector<std::vector<ColourComparison>> compare_colours(
    const std::vector<ColourCatalogue>& catalogues, double mag_limit, int resamples,
    std::uint64_t seed);

/// The markdown report: the comparisons (per colour: n, mean ± error, offset in σ, KS D and p
/// of colours and of gradients) and the colour–magnitude table (median colour per 1-mag bin).
void write_colour_report(std::ostream& out, const std::vector<ColourCatalogue>& catalogues,
                         const std::vector<std::vector<ColourComparison>>& comparisons,
                         double mag_limit);

}  // namespace shapesim
