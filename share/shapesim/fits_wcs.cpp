// The FITS side of a WCS: a header's celestial WCS keywords (wcslib evaluates them) and the
// geometry of a `--like` image, read through cfitsio (declared in fits_io.hpp; the WCS itself is
// geometry.hpp's).
#include "shapesim/fits_io.hpp"

#include "shapesim/constants.hpp"
#include "shapesim/error.hpp"

#include <cmath>
#include <optional>
#include <string>

namespace shapesim {

namespace {

std::string trimmed(std::string s) {
    while (!s.empty() && s.back() == ' ') s.pop_back();
    return s;
}

// The CD matrix of the current HDU, by the three FITS conventions in order of precedence
// (Calabretta & Greisen 2002 §2.1.2; CROTA2 as in the AIPS convention).
void read_cd(FitsReader& fits, WcsKeywords& w) {
    if (fits.optional_double("CD1_1") || fits.optional_double("CD2_2")) {
        w.cd1_1 = fits.optional_double("CD1_1").value_or(0.0);
        w.cd1_2 = fits.optional_double("CD1_2").value_or(0.0);
        w.cd2_1 = fits.optional_double("CD2_1").value_or(0.0);
        w.cd2_2 = fits.optional_double("CD2_2").value_or(0.0);
        return;
    }
    const double cdelt1 = fits.required_double("CDELT1");
    const double cdelt2 = fits.required_double("CDELT2");
    if (fits.optional_double("PC1_1") || fits.optional_double("PC2_2")) {
        w.cd1_1 = cdelt1 * fits.optional_double("PC1_1").value_or(1.0);
        w.cd1_2 = cdelt1 * fits.optional_double("PC1_2").value_or(0.0);
        w.cd2_1 = cdelt2 * fits.optional_double("PC2_1").value_or(0.0);
        w.cd2_2 = cdelt2 * fits.optional_double("PC2_2").value_or(1.0);
        return;
    }
    const double rho = fits.optional_double("CROTA2").value_or(0.0) * degree;
    w.cd1_1 = cdelt1 * std::cos(rho);
    w.cd1_2 = -cdelt2 * std::sin(rho);
    w.cd2_1 = cdelt1 * std::sin(rho);
    w.cd2_2 = cdelt2 * std::cos(rho);
}

// The SIP keywords of the current HDU: A_ORDER/B_ORDER and every A_p_q/B_p_q with
// 2 ≤ p + q ≤ order (absent terms are 0).
void read_sip(FitsReader& fits, WcsKeywords& w) {
    const auto order_of = [&](const char* key) {
        const long long order = fits.required_int(key);
        if (order < 2 || order > 9)
            throw Error("SIP order must be 2 to 9, got " + std::to_string(order), fits.place(), 0,
                        key);
        return int(order);
    };
    const int a_order = order_of("A_ORDER"), b_order = order_of("B_ORDER");
    w.sip_order = std::max(a_order, b_order);
    const auto terms = [&](const char* prefix, int order) {
        std::vector<std::vector<double>> c(std::size_t(w.sip_order + 1),
                                           std::vector<double>(std::size_t(w.sip_order + 1), 0.0));
        for (int p = 0; p <= order; ++p)
            for (int q = 0; p + q <= order; ++q)
                if (p + q >= 1)
                    c[std::size_t(p)][std::size_t(q)] =
                        fits.optional_double(std::string(prefix) + "_" + std::to_string(p) + "_" +
                                             std::to_string(q))
                            .value_or(0.0);
        return c;
    };
    w.sip_a = terms("A", a_order);
    w.sip_b = terms("B", b_order);
}

// PVi_m, i = 1, 2: the projection's parameters and TPV's terms (m ≤ 99, as FITS allows).
void read_pv(FitsReader& fits, WcsKeywords& w) {
    for (int i = 1; i <= 2; ++i)
        for (int m = 0; m <= 99; ++m)
            if (auto v = fits.optional_double("PV" + std::to_string(i) + "_" + std::to_string(m)))
                w.pv.push_back({i, m, *v});
}

}  // namespace

bool has_wcs(FitsReader& fits) {
    // A blank CTYPE1 (some pipelines write one with CDELT 1) declares no celestial WCS.
    const std::optional<std::string> ctype = fits.optional_string("CTYPE1");
    return ctype && ctype->find_first_not_of(' ') != std::string::npos;
}

Wcs read_wcs(FitsReader& fits) {
    WcsKeywords w;
    w.ctype1 = fits.required_string("CTYPE1");
    w.ctype2 = fits.required_string("CTYPE2");
    w.crpix1 = fits.required_double("CRPIX1");
    w.crpix2 = fits.required_double("CRPIX2");
    w.crval1 = fits.required_double("CRVAL1");
    w.crval2 = fits.required_double("CRVAL2");
    read_cd(fits, w);
    if (trimmed(w.ctype1).size() > 8 && trimmed(w.ctype1).substr(8) == "-SIP") read_sip(fits, w);
    read_pv(fits, w);
    w.lonpole = fits.optional_double("LONPOLE");
    w.latpole = fits.optional_double("LATPOLE");
    if (auto radesys = fits.optional_string("RADESYS"); radesys && !trimmed(*radesys).empty())
        w.radesys = trimmed(*radesys);
    try {
        return Wcs(std::move(w));
    } catch (const Error& e) {
        throw e.at(fits.place());
    }
}

FieldGeometry read_field_geometry(const std::string& path, std::optional<double> pixel_scale,
                                  double ra, double dec) {
    FitsReader fits(path, FitsStart::first_image);
    FieldGeometry g;
    const auto [nx, ny] = fits.image_size();
    g.nx = nx;
    g.ny = ny;
    if (has_wcs(fits)) {
        g.wcs = read_wcs(fits);
    } else if (pixel_scale) {
        g.wcs = tan_wcs(ra, dec, *pixel_scale, (nx + 1) / 2.0, (ny + 1) / 2.0);
    } else {
        throw Error("no WCS in the header: give --pixel-scale (and --ra/--dec)", fits.place());
    }
    g.pixel_scale = g.wcs.pixel_scale_arcsec();
    g.bunit = fits.optional_string("BUNIT").value_or("");
    if (const auto level = fits.optional_double("SATURATE");
        level && *level > 0.0 && std::isfinite(*level))
        g.saturate = *level;
    return g;
}

}  // namespace shapesim
