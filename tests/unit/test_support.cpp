#include "test_support.hpp"

#include <cstdlib>
#include <filesystem>
#include <stdexcept>
#include <unistd.h>

#include "shapesim/basis1d.hpp"
#include "shapesim/decompose.hpp"
#include "shapesim/morphology.hpp"
#include "shapesim/moments.hpp"
#include "shapesim/fits_io.hpp"
#include "shapesim/jsonl.hpp"
#include "shapesim/polar.hpp"
#include "shapesim/render.hpp"
#include "shapesim/rng.hpp"
#include "shapesim/transform.hpp"

#include <fitsio.h>

#include <cstddef>  // sep.h uses size_t without including it
extern "C" {        // sep.h has no C++ guards
#include <sep.h>
}

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <map>
#include <mutex>
#include <stdexcept>
#include <sys/stat.h>

namespace shapesim::test {

namespace {
bool is_dir(const std::string& path) {
    struct stat st;
    return stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode);
}
}  // namespace

const std::string& source_dir() {
    static const std::string dir = [] {
        if (const char* env = std::getenv("SHAPESIM_SOURCE_DIR"); env && *env) return std::string(env);
        std::string exe(4096, '\0');
        const ssize_t n = readlink("/proc/self/exe", exe.data(), exe.size() - 1);
        if (n <= 0) throw std::runtime_error("test_support: cannot read /proc/self/exe");
        exe.resize(std::size_t(n));
        std::string dir = exe;
        for (int up = 0; up < 3; ++up) dir = dir.substr(0, dir.find_last_of('/'));
        return dir;
    }();
    return dir;
}

std::string reference_dir() {
    const std::string in_repo = source_dir() + "/tests/data/reference";
    if (is_dir(in_repo)) return in_repo;
    if (const char* env = std::getenv("SHAPESIM_DATA"))
        if (is_dir(std::string(env) + "/reference")) return std::string(env) + "/reference";
    return in_repo;  // missing: the readers fail naming it
}

ImageArray read_fits_image(const std::string& path, int hdu) {
    fitsfile* f = nullptr;
    int status = 0, type = 0, naxis = 0;
    long naxes[2] = {0, 0}, first[2] = {1, 1};
    fits_open_file(&f, path.c_str(), READONLY, &status);
    fits_movabs_hdu(f, hdu, &type, &status);
    fits_get_img_dim(f, &naxis, &status);
    fits_get_img_size(f, 2, naxes, &status);
    ImageArray image(naxes[1], naxes[0]);
    fits_read_pix(f, TDOUBLE, first, naxes[0] * naxes[1], nullptr, image.data(), nullptr, &status);
    int close_status = 0;
    if (f) fits_close_file(f, &close_status);
    if (status) throw std::runtime_error("cannot read " + path + " HDU " + std::to_string(hdu));
    return image;
}

const std::vector<ReferenceModel>& reference_models() {
    static std::once_flag once;
    static std::vector<ReferenceModel> models;
    std::call_once(once, [] {
        JsonlReader in(reference_dir() + "/models.jsonl", {ShapeletRecord::schema});
        int hdu = 2;  // stamps.fits: empty primary, then one HDU per model in file order
        for (ShapeletRecord record; in.next_record(record);) {
            ReferenceModel r;
            r.id = record.id;
            r.model = record.to_model();
            r.flux = record.flux.value();
            r.stamp = read_fits_image(reference_dir() + "/stamps.fits", hdu++);
            r.nx = int(r.stamp.cols());
            r.ny = int(r.stamp.rows());
            models.push_back(std::move(r));
        }
    });
    return models;
}

const std::vector<ReferenceConvolution>& reference_convolutions() {
    static std::once_flag once;
    static std::vector<ReferenceConvolution> lines;
    std::call_once(once, [] {
        std::map<std::string, const ShapeletModel*> galaxies;
        for (const auto& m : reference_models()) galaxies[m.id] = &m.model;
        const std::string dir = reference_dir();
        JsonlReader in(dir + "/convolved.jsonl", {ReferenceConvolutionRecord::schema});
        for (ReferenceConvolutionRecord record; in.next_record(record);) {
            ReferenceConvolution r;
            r.galaxy = *galaxies.at(record.galaxy_id);
            r.galaxy.x = record.x;  // the convolved stamp's centre (README)
            r.galaxy.y = record.y;
            r.psf = record.psf.to_model();
            r.result = record.result.to_model();
            r.image = shapesim::read_fits_image(dir + "/convolved.fits[" + record.hdu + "]");
            r.record = std::move(record);
            lines.push_back(std::move(r));
        }
    });
    return lines;
}

void gauss_legendre(int n, std::vector<double>& nodes, std::vector<double>& weights) {
    nodes.resize(n);
    weights.resize(n);
    for (int i = 0; i < n; ++i) {
        double x = std::cos(M_PI * (i + 0.75) / (n + 0.5)), dp = 0.0;
        for (int iter = 0; iter < 100; ++iter) {
            double p0 = 1.0, p1 = x;
            for (int k = 2; k <= n; ++k) {
                const double p2 = ((2.0 * k - 1.0) * x * p1 - (k - 1.0) * p0) / k;
                p0 = p1;
                p1 = p2;
            }
            dp = n * (x * p1 - p0) / (x * x - 1.0);
            const double dx = p1 / dp;
            x -= dx;
            if (std::abs(dx) < 1e-16) break;
        }
        nodes[i] = x;
        weights[i] = 2.0 / ((1.0 - x * x) * dp * dp);
    }
}

double integrate(const std::function<double(double)>& f, double a, double b, int panels,
                 int order) {
    std::vector<double> nodes, weights;
    gauss_legendre(order, nodes, weights);
    const double h = (b - a) / panels;
    double sum = 0.0;
    for (int p = 0; p < panels; ++p) {
        const double mid = a + (p + 0.5) * h;
        for (int i = 0; i < order; ++i) sum += weights[i] * f(mid + 0.5 * h * nodes[i]);
    }
    return 0.5 * h * sum;
}

double integrate_pixel(const std::function<double(double, double)>& f, double x, double y,
                       int order) {
    std::vector<double> nodes, weights;
    gauss_legendre(order, nodes, weights);
    double sum = 0.0;
    for (int a = 0; a < order; ++a)
        for (int b = 0; b < order; ++b)
            sum += 0.25 * weights[a] * weights[b] * f(x + 0.5 * nodes[a], y + 0.5 * nodes[b]);
    return sum;
}

double tensor_brute_force_error(const ConvolutionTensor& c, const std::vector<double>& xs,
                                double step, double half_width) {
    const int n_f = c.n_f(), n_g = c.n_g(), points = int(2 * half_width / step) + 1;
    std::vector<double> fa(n_f + 1), gb(n_g + 1), hl(c.n_out() + 1);
    double worst = 0.0;
    for (const double x : xs) {
        Eigen::MatrixXd brute = Eigen::MatrixXd::Zero(n_f + 1, n_g + 1);
        for (int p = 0; p < points; ++p) {
            const double xp = -half_width + p * step;
            hermite_functions(xp / c.alpha(), n_f, fa.data());
            hermite_functions((x - xp) / c.b(), n_g, gb.data());
            for (int n = 0; n <= n_f; ++n)
                for (int m = 0; m <= n_g; ++m)
                    brute(n, m) += step * fa[n] * gb[m] / std::sqrt(c.alpha() * c.b());
        }
        hermite_functions(x / c.gamma(), c.n_out(), hl.data());
        for (int n = 0; n <= n_f; ++n)
            for (int m = 0; m <= n_g; ++m) {
                double series = 0.0;
                for (int l = 0; l <= c.n_out(); ++l)
                    series += c(n, m, l) * hl[l] / std::sqrt(c.gamma());
                worst = std::max(worst, std::abs(series - brute(n, m)));
            }
    }
    return worst;
}

double lattice_convolution_error(const ShapeletModel& f, const ShapeletModel& g,
                                 const ShapeletModel& h, double step, int p_max, int q_max,
                                 int stride) {
    // Each model sampled out to β(√(2n+1) + 9), far past its last oscillation.
    const auto sample = [step](const ShapeletModel& model, int& r) {
        r = int(model.beta_pix * (std::sqrt(2.0 * model.n_max + 1) + 9) / step);
        Eigen::MatrixXd s(2 * r + 1, 2 * r + 1);
        for (int i = -r; i <= r; ++i)
            for (int j = -r; j <= r; ++j)
                s(i + r, j + r) = evaluate(model, model.x + i * step, model.y + j * step);
        return s;
    };
    int rf = 0, rg = 0;
    const Eigen::MatrixXd fs = sample(f, rf), gs = sample(g, rg);
    double worst = 0.0, peak = 0.0;
    for (int p = -p_max; p <= p_max; p += stride)
        for (int q = -q_max; q <= q_max; q += stride) {
            double sum = 0.0;
            for (int i = std::max(-rf, p - rg); i <= std::min(rf, p + rg); ++i)
                for (int j = std::max(-rf, q - rg); j <= std::min(rf, q + rg); ++j)
                    sum += fs(i + rf, j + rf) * gs(p - i + rg, q - j + rg);
            const double value = evaluate(h, h.x + p * step, h.y + q * step);
            worst = std::max(worst, std::abs(value - sum * step * step));
            peak = std::max(peak, std::abs(value));
        }
    return worst / peak;
}

ShapeletModel random_model(std::mt19937_64& engine, int n_max, double beta_pix, double x,
                           double y, bool galaxy, double amplitude) {
    std::normal_distribution<double> normal;
    ShapeletModel model(x, y, beta_pix, n_max);
    int k = 0;
    for (const auto& [n, m] : polar_indices(n_max)) {
        const double scale = galaxy ? amplitude * std::exp(-n / 5.0) : 1.0;
        model.coeffs[k++] = Complex(scale * normal(engine), m == 0 ? 0.0 : scale * normal(engine));
    }
    if (galaxy) model.coeffs[0] = Complex(1.0, 0.0);
    return model;
}

ShapeletModel random_model(int n_max, double beta_pix, double x, double y, unsigned seed,
                           bool galaxy, double amplitude) {
    std::mt19937_64 engine(seed);
    return random_model(engine, n_max, beta_pix, x, y, galaxy, amplitude);
}

SyntheticField synthetic_field(int nx, int ny, double spacing, double flux_min, double flux_max,
                               double noise_sigma, std::uint64_t seed, double psf_sigma,
                               int star_every) {
    constexpr double pi = 3.14159265358979323846;
    SyntheticField field;
    field.image = ImageArray::Zero(ny, nx);
    field.weight = ImageArray::Constant(ny, nx, 1.0 / (noise_sigma * noise_sigma));
    RenderWorkspace workspace;
    const double margin = 8.0;
    int index = 0;
    for (double yc = margin + spacing / 2; yc < ny - margin; yc += spacing)
        for (double xc = margin + spacing / 2; xc < nx - margin; xc += spacing, ++index) {
            RandomStream r(seed, std::uint64_t(index), "synthetic object");
            SyntheticObject o;
            o.x = xc + r.uniform(-0.25, 0.25) * spacing;
            o.y = yc + r.uniform(-0.25, 0.25) * spacing;
            o.flux = flux_min * std::pow(flux_max / flux_min, r.uniform());
            o.star = star_every > 0 && index % star_every == 0;
            ShapeletModel model;
            if (o.star) {
                o.sigma = psf_sigma;
                model = ShapeletModel(o.x, o.y, psf_sigma, 0);
                model.at(0, 0) = Complex(o.flux / (2.0 * std::sqrt(pi) * psf_sigma), 0.0);
            } else {
                o.sigma = psf_sigma * r.uniform(1.2, 3.0);
                const double g = 0.4 * std::sqrt(r.uniform()), angle = r.angle();
                o.g1 = g * std::cos(angle);
                o.g2 = g * std::sin(angle);
                ShapeletModel round(o.x, o.y, o.sigma, 0);
                round.at(0, 0) = Complex(o.flux / (2.0 * std::sqrt(pi) * o.sigma), 0.0);
                ProjectionOptions options;
                options.tolerance = 1e-9;
                model = shear(round, o.g1, o.g2, options).model;
            }
            const int half = int(std::ceil(6.0 * o.sigma * 1.6)) + 2;
            const PixelWindow window{int(o.x) - 1 - half, int(o.y) - 1 - half, 2 * half + 1,
                                     2 * half + 1};
            add_to_image(to_cartesian(model), field.image, window.clipped_to(nx, ny), workspace);
            field.objects.push_back(o);
        }
    RandomStream noise(seed, "field", "synthetic noise");
    for (Eigen::Index k = 0; k < field.image.size(); ++k)
        field.image.data()[k] += noise_sigma * noise.gaussian();
    return field;
}


ShapeletModel centred_galaxy(int n_max, double beta, int side, unsigned seed, double flux) {
    ShapeletModel m = random_model(n_max, beta, (side + 1) / 2.0 + 0.3, (side + 1) / 2.0 - 0.2,
                                   seed, true, 0.3);
    // Centroid ∝ Σ_{n odd} √(n+1) conj a_{n,1} = 0:
    Complex z = 0.0;
    for (int n = 3; n <= n_max; n += 2) z += std::sqrt(n + 1.0) * m.at(n, 1);
    if (n_max >= 1) m.at(1, 1) = -z / std::sqrt(2.0);
    const double f = shapesim::flux(m);
    for (auto& c : m.coeffs) c *= flux / f;
    return m;
}

ImageArray noisy_stamp(const ShapeletModel& model, int side, double sigma, std::uint64_t seed,
                       std::uint64_t id) {
    ImageArray image = render_stamp(model, side, side);
    RandomStream r(seed, id, "noise");
    for (Eigen::Index k = 0; k < image.size(); ++k) image.data()[k] += sigma * r.gaussian();
    return image;
}

DecomposeGrid decompose_grid(int seeds) {
    constexpr double pi = 3.14159265358979323846;
    const int side = 61;
    DecomposeGrid g;
    for (int truth_n : {2, 4, 8, 12})
        // β within the constraints (θ_min = 1 px ⇒ β ≥ √(n+1)), two sizes per order.
        for (double beta : {1.15 * std::sqrt(truth_n + 1.0), 1.6 * std::sqrt(truth_n + 1.0)})
            for (double snr : {10.0, 100.0, 1000.0})
                for (int seed = 0; seed < seeds; ++seed) {
                    const ShapeletModel truth =
                        centred_galaxy(truth_n, beta, side, 100 + unsigned(seed), 1.0);
                    const double sigma = 1.0 / (snr * std::sqrt(4.0 * pi) * 2.0 * beta);
                    const ImageArray image = noisy_stamp(
                        truth, side, sigma, 7,
                        std::uint64_t(truth_n * 1000 + seed) * 31 + std::uint64_t(snr));
                    const ImageArray weight =
                        ImageArray::Constant(side, side, 1.0 / (sigma * sigma));
                    const Decomposition d = decompose(image, weight, nullptr, truth.x, truth.y,
                                                      beta, DecomposeOptions{});
                    ++g.cases;
                    const int excess = d.fit.model.n_max - truth_n;
                    g.max_excess = std::max(g.max_excess, excess);
                    if (excess > 2) ++g.over;
                    g.snr.push_back(snr);
                    g.pull.push_back((shapesim::flux(d.fit.model) - 1.0) / d.flux_error);
                    if (d.converged) g.converged_chi2r.push_back(d.chi2r);
                }
    return g;
}

MeanRms mean_rms(const std::vector<double>& v, const std::vector<double>& key,
                 const std::function<bool(double)>& keep) {
    MeanRms r;
    double sum = 0.0, sum2 = 0.0;
    for (std::size_t k = 0; k < v.size(); ++k)
        if (keep(key[k])) {
            ++r.n;
            sum += v[k];
        }
    if (r.n == 0) return r;
    r.mean = sum / double(r.n);
    for (std::size_t k = 0; k < v.size(); ++k)
        if (keep(key[k])) sum2 += (v[k] - r.mean) * (v[k] - r.mean);
    r.rms = std::sqrt(sum2 / double(r.n));
    r.error = r.rms / std::sqrt(double(r.n));
    return r;
}

Morphology synthetic_morphology(bool heavy) {
    // The HDF cut's smoothed models: n_max 0 ×147, 2 ×2, 3 ×4, 4 ×2, 5, 6 ×3, 7 (of 160).
    auto hdf_order = [](int i) {
        static const int tail[13] = {2, 2, 3, 3, 3, 3, 4, 4, 5, 6, 6, 6, 7};
        const int k = i % 160;
        return k < 147 ? 0 : tail[k - 147];
    };
    std::vector<ShapeletRecord> records;
    for (int i = 0; records.size() < 200; ++i) {
        ShapeletModel model =
            test::random_model(heavy ? i % 16 : hdf_order(i), 1.0 + 4.0 * ((i * 37) % 100) / 100.0,
                               0.0, 0.0, 1000 + unsigned(i), true, 0.2);
        if (flux(model) <= 0.0) continue;
        ShapeletRecord r = ShapeletRecord::from_model(model, 0.04, std::to_string(i));
        r.mag = 22.0 + 7.0 * ((i * 61) % 100) / 100.0;
        r.extra["zero_point"] = 25.0;
        records.push_back(r);
    }
    return build_morphology(records, SmoothOptions{});
}

double ks_p_value(std::vector<double> sample, const std::function<double(double)>& cdf) {
    std::sort(sample.begin(), sample.end());
    const double n = double(sample.size());
    double d = 0.0;
    for (size_t i = 0; i < sample.size(); ++i) {
        const double f = cdf(sample[i]);
        d = std::max({d, std::abs(f - i / n), std::abs((i + 1) / n - f)});
    }
    const double lambda = (std::sqrt(n) + 0.12 + 0.11 / std::sqrt(n)) * d;
    double sum = 0.0, sign = 1.0;
    for (int j = 1; j <= 100; ++j, sign = -sign)
        sum += sign * 2.0 * std::exp(-2.0 * j * j * lambda * lambda);
    return std::clamp(sum, 0.0, 1.0);
}

namespace {

sep_image sep_view_of(const std::vector<double>& data, int w, int h) {
    sep_image im{};
    im.data = data.data();
    im.dtype = SEP_TDOUBLE;
    im.w = w;
    im.h = h;
    im.noise_type = SEP_NOISE_NONE;
    return im;
}

}  // namespace

double sep_circle_sum(const std::vector<double>& data, int w, int h, double x, double y,
                      double r) {
    const sep_image im = sep_view_of(data, w, h);
    double sum = 0.0, err = 0.0, area = 0.0;
    short flag = 0;
    if (sep_sum_circle(&im, x, y, r, 0, 0, 0, &sum, &err, &area, &flag) != 0)
        return std::numeric_limits<double>::quiet_NaN();
    return sum;
}

double sep_ellipse_sum(const std::vector<double>& data, int w, int h, double x, double y,
                       double a, double b, double theta) {
    const sep_image im = sep_view_of(data, w, h);
    double sum = 0.0, err = 0.0, area = 0.0;
    short flag = 0;
    if (sep_sum_ellipse(&im, x, y, 1.0, b / a, theta, a, 0, 0, 0, &sum, &err, &area, &flag) != 0)
        return std::numeric_limits<double>::quiet_NaN();
    return sum;
}

TempDir::TempDir() {
    char pattern[] = "/tmp/shapesim-test-XXXXXX";
    if (!mkdtemp(pattern)) throw std::runtime_error("mkdtemp failed");
    path_ = pattern;
}

TempDir::~TempDir() {
    std::error_code ignored;
    std::filesystem::remove_all(path_, ignored);
}

}  // namespace shapesim::test
