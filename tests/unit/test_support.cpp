#include "test_support.hpp"

#include <fitsio.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <mutex>
#include <random>
#include <stdexcept>
#include <sys/stat.h>

namespace shapesim::test {

namespace {
bool is_dir(const std::string& path) {
    struct stat st;
    return stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode);
}
std::string repo_root() { return SHAPESIM_SOURCE_DIR; }  // set by tests/module.mk
}  // namespace

std::string reference_dir() {
    const std::string in_repo = repo_root() + "/tests/data/reference";
    if (is_dir(in_repo)) return in_repo;
    if (const char* env = std::getenv("SHAPESIM_DATA"))
        if (is_dir(std::string(env) + "/reference")) return std::string(env) + "/reference";
    return repo_root() + "/../shared/data/reference";
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
        std::ifstream in(reference_dir() + "/models.jsonl");
        if (!in) throw std::runtime_error("no reference models in " + reference_dir());
        std::string line;
        int hdu = 2;  // stamps.fits: empty primary, then one HDU per model in file order
        while (std::getline(in, line)) {
            const auto j = nlohmann::json::parse(line);
            ReferenceModel r;
            r.id = j.at("id");
            r.model = ShapeletModel(j.at("x"), j.at("y"),
                                    double(j.at("beta")) / double(j.at("pixel_scale")),
                                    j.at("n_max"));
            int k = 0;
            for (const auto& c : j.at("coeffs")) r.model.coeffs[k++] = Complex(c[0], c[1]);
            r.stamp = read_fits_image(reference_dir() + "/stamps.fits", hdu++);
            r.nx = int(r.stamp.cols());
            r.ny = int(r.stamp.rows());
            models.push_back(std::move(r));
        }
    });
    return models;
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

ShapeletModel random_model(int n_max, double beta_pix, double x, double y, unsigned seed,
                           bool galaxy) {
    std::mt19937_64 engine(seed);
    std::normal_distribution<double> normal;
    ShapeletModel model(x, y, beta_pix, n_max);
    int k = 0;
    for (const auto& [n, m] : polar_indices(n_max)) {
        const double scale = galaxy ? 0.35 * std::exp(-n / 5.0) : 1.0;
        model.coeffs[k++] = Complex(scale * normal(engine), m == 0 ? 0.0 : scale * normal(engine));
    }
    if (galaxy) model.coeffs[0] = Complex(1.0, 0.0);
    return model;
}

}  // namespace shapesim::test
