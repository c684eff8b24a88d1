// The real fields shapesim-smooth's records come from: --like IMAGE, --area, or --field
// IMAGE=ARCMIN2[@MAG] / IMAGE=shapes repeated (morphology.hpp's SourceField). Read here, where
// a wrong value is an option's error.
#pragma once

#include "shapesim/morphology.hpp"

#include <optional>
#include <string>
#include <vector>

namespace shapesim::app {

struct SourceFields {
    std::vector<SourceField> counted;       ///< the fields whose galaxies are counted
    std::vector<bool> completeness_given;   ///< per --field counted field: @MAG given
    std::vector<std::string> shape_images;  ///< shape-only fields (IMAGE=shapes)

    /// Every --field image: the counted fields', then the shape-only ones.
    std::vector<std::string> images() const;
    /// Sort each counted field's magnitudes; where --field gave no @MAG, its counts are complete
    /// to their turnover (count_turnover()).
    void complete();
};

/// One of --like (its area from the image's WCS or `pixel_scale`), --area and --field
/// (`specs`); none: no field. po::error on a malformed or repeated spec, or more than one.
SourceFields read_source_fields(const std::string& like, std::optional<double> area,
                                std::optional<double> pixel_scale,
                                const std::vector<std::string>& specs);

/// --stars [IMAGE=]FILE, repeated: each file's star records (shapesim-detect --stars) counted in
/// the field IMAGE, or in the one counted field when IMAGE= is left out (SourceField::star_mags;
/// stars without a magnitude are skipped). po::error when there is no counted field, IMAGE is
/// none of them, IMAGE= is left out with several, or a field is given twice; Error naming
/// the file and line on a bad record.
void add_field_stars(SourceFields& fields, const std::vector<std::string>& specs);

}  // namespace shapesim::app
