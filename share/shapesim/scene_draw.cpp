// A window of the field drawn: the prepared objects painted (in bands of rows, or strip by
// strip for a sink), the sky, photon and background noise added, each step timed.
#include "shapesim/scene.hpp"

#include "shapesim/error.hpp"
#include "shapesim/lane_math.hpp"
#include "shapesim/parallel.hpp"
#include "shapesim/pixel_noise.hpp"
#include "shapesim/render.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <mutex>
#include <tuple>

namespace shapesim {

namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point start) {
    return std::chrono::duration<double>(Clock::now() - start).count();
}

// to[c] += from[c] for c < n, or += max(from[c], 0) when `clip` (negative light left out), four
// pixels a lane group (each pixel its own sum: the same bits as one at a time).
__attribute__((target_clones("avx2", "default"))) void add_stamp_row(
    double* __restrict to, const double* __restrict from, long n, bool clip) {
    using lane::Doubles4;
    long c = 0;
    for (; c + 4 <= n; c += 4) {
        Doubles4 sum, light;
        std::memcpy(&sum, to + c, sizeof sum);
        std::memcpy(&light, from + c, sizeof light);
        if (clip) light = light < 0.0 ? Doubles4{} : light;
        sum += light;
        std::memcpy(to + c, &sum, sizeof sum);
    }
    for (; c < n; ++c) to[c] += clip ? std::max(from[c], 0.0) : from[c];
}

}  // namespace

ImageArray paint(const std::vector<PreparedObject>& objects, const Tile& window,
                 const SceneOptions& options, std::vector<ClippedLight>* clipped) {
    const long nx = window.x1 - window.x0 + 1, ny = window.y1 - window.y0 + 1;
    require(nx > 0 && ny > 0, "empty window");
    ImageArray image = large_image(ny, nx);
    paint_into(image, objects, window, options, clipped);
    return image;
}

void paint_into(ImageArray& image, const std::vector<PreparedObject>& objects, const Tile& window,
                const SceneOptions& options, std::vector<ClippedLight>* clipped) {
    const long nx = window.x1 - window.x0 + 1, ny = window.y1 - window.y0 + 1;
    require(nx > 0 && ny > 0, "empty window");
    // Each band zeroes its own rows: pages first touched by a write are mapped writable at
    // once, where calloc's zero pages fault again, copy on write, and flush the TLB of every
    // other thread (painting on two threads was slower than on one).
    if (image.rows() != ny || image.cols() != nx) image = large_image(ny, nx);
    if (clipped) clipped->assign(objects.size(), ClippedLight{});
    parallel_bands(ny, options.threads, [&](long first, long last) {
        std::fill(&image(first, 0), &image(first, 0) + (last - first) * nx, 0.0);
        RenderWorkspace ws;
        // Band rows in field 0-based coordinates: [window.y0 − 1 + first, … + last).
        const long row_lo = window.y0 - 1 + first, row_hi = window.y0 - 1 + last;
        const long col_lo = window.x0 - 1, col_hi = window.x1;
        // The stamps reaching this band, added in order of their first row, then column, then
        // catalogue place: a sweep down the band keeps the rows being added to in cache (three
        // times faster than catalogue order, which jumps about the image), and any tiling or
        // banding adds a pixel's stamps in the same order, so gives the same bits.
        std::vector<std::size_t> order;
        for (std::size_t i = 0; i < objects.size(); ++i) {
            const PixelWindow& w = objects[i].window;
            if (objects[i].drawn && w.row0 < row_hi && w.row0 + w.ny > row_lo &&
                w.column0 < col_hi && w.column0 + w.nx > col_lo)
                order.push_back(i);
        }
        std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
            const PixelWindow &wa = objects[a].window, &wb = objects[b].window;
            return std::tie(wa.row0, wa.column0, a) < std::tie(wb.row0, wb.column0, b);
        });
        for (const std::size_t i : order) {
            const PreparedObject& o = objects[i];
            const PixelWindow& w = o.window;
            const long r0 = std::max<long>(w.row0, row_lo),
                       r1 = std::min<long>(w.row0 + w.ny, row_hi);
            const long c0 = std::max<long>(w.column0, col_lo),
                       c1 = std::min<long>(w.column0 + w.nx, col_hi);
            // The whole stamp, whatever the window, then its overlap (negative light clipped
            // there, as it is added, where the stamp dips below zero).
            Eigen::Map<ImageArray> stamp(render_window(o.model, w, ws), w.ny, w.nx);
            bool clip = false;
            if (options.clip_negative && o.kind == "galaxy") {
                const double deepest = stamp.minCoeff();
                clip = deepest < 0.0;
                // The band holding the stamp's first overlapping row reports it (once).
                if (clip && clipped && r0 == std::max<long>(w.row0, window.y0 - 1))
                    (*clipped)[i] = ClippedLight{-(stamp.cwiseMin(0.0).sum()), deepest};
            }
            for (long r = r0; r < r1; ++r)
                add_stamp_row(&image(r - (window.y0 - 1), c0 - (window.x0 - 1)),
                              &stamp(r - w.row0, c0 - w.column0), c1 - c0, clip);
        }
    });
}

ImageArray noise_scale_from_weight(const ImageArray& weight) {
    double sum = 0.0;
    long good = 0;
    for (Eigen::Index k = 0; k < weight.size(); ++k) {
        const double w = weight.data()[k];
        if (w > 0.0 && std::isfinite(w)) {
            sum += 1.0 / w;
            ++good;
        }
    }
    require(good > 0, "the noise weight map has no pixel with a positive weight");
    const double mean_variance = sum / double(good);
    ImageArray scale = large_image(weight.rows(), weight.cols());
    for (Eigen::Index k = 0; k < weight.size(); ++k) {
        const double w = weight.data()[k];
        scale.data()[k] = w > 0.0 && std::isfinite(w) ? 1.0 / std::sqrt(w * mean_variance) : 1.0;
    }
    return scale;
}

namespace {

// pixels[i] += σ · local[i] · n[i] (without `local`: σ · n[i]), four pixels a lane group; each
// pixel the same operations in the same order as one at a time, so the same bits.
__attribute__((target_clones("avx2", "default"))) void add_background(
    double* __restrict pixels, const float* __restrict n, double sigma,
    const double* __restrict local, long nx) {
    using Doubles4 = double __attribute__((vector_size(32)));
    using Floats4 = float __attribute__((vector_size(16)));
    long i = 0;
    for (; i + 4 <= nx; i += 4) {
        Doubles4 p, scale = {sigma, sigma, sigma, sigma};
        Floats4 deviate;
        std::memcpy(&p, pixels + i, sizeof p);
        std::memcpy(&deviate, n + i, sizeof deviate);
        if (local) {
            Doubles4 l;
            std::memcpy(&l, local + i, sizeof l);
            scale = scale * l;
        }
        p = p + scale * __builtin_convertvector(deviate, Doubles4);
        std::memcpy(pixels + i, &p, sizeof p);
    }
    for (; i < nx; ++i) pixels[i] += (local ? sigma * local[i] : sigma) * double(n[i]);
}

}  // namespace

void add_noise(ImageArray& image, const Tile& window, long field_nx, const SceneOptions& options) {
    if (options.noise_free) return;
    const long nx = window.x1 - window.x0 + 1, ny = window.y1 - window.y0 + 1;
    require(image.rows() == ny && image.cols() == nx, "add_noise: image and window differ");
    const NoiseKernel kernel = options.noise_kernel
                                   ? *options.noise_kernel
                                   : drizzle_noise_kernel(options.noise_correlation);
    require(kernel.radius <= max_noise_kernel_radius, "add_noise: the noise kernel is too wide");
    const ImageArray* scale = options.noise_scale ? &*options.noise_scale : nullptr;
    require(!scale ||
                (scale->cols() == field_nx && scale->rows() >= window.y1 && window.x1 <= field_nx),
            "add_noise: the noise scale map does not cover the field");
    const double sigma = options.noise_rms;
    // Photon noise only where it adds at least `photon_tolerance` of the background variance:
    // elsewhere it would change nothing measurable (all pixels when there is no background).
    // Its variance is s/gain, so the test is s ≥ photon_floor · gain (and s > 0).
    const bool photons = options.gain > 0.0;
    const double photon_signal = options.photon_tolerance * sigma * sigma * options.gain;
    parallel_bands(ny, options.threads, [&](long first, long last) {
        if (first >= last) return;
        CorrelatedNoise background(kernel, options.seed, window.x0 - 1, nx);
        const PhotonNoise photon(options.seed);
        std::vector<float> mapped(options.noise_marginal.empty() ? 0 : std::size_t(nx));
        for (long j = first; j < last; ++j) {
            const long row = window.y0 - 1 + j;  // field 0-based
            double* pixels = &image(j, 0);
            // Photon noise (and the sky level) first: it follows the noise-free signal.
            if (options.sky != 0.0)
                for (long i = 0; i < nx; ++i) pixels[i] += options.sky;
            if (photons) photon.row(row, window.x0 - 1, nx, options.gain, photon_signal, pixels);
            if (sigma > 0.0) {
                // The background's local σ: the scale map's, keyed by the field pixel.
                const float* n = background.row(row);
                if (!mapped.empty()) {
                    options.noise_marginal.map(n, mapped.data(), nx);
                    n = mapped.data();
                }
                add_background(pixels, n, sigma, scale ? &(*scale)(row, window.x0 - 1) : nullptr,
                               nx);
            }
            if (options.saturation > 0.0)
                for (long i = 0; i < nx; ++i) pixels[i] = std::min(pixels[i], options.saturation);
        }
    });
}

RenderedScene render_field(const std::vector<ObjectRecord>& records, const FieldGeometry& field,
                           const SceneKernels& kernels, const SceneOptions& options,
                           const Tile& window, const std::string& source) {
    RenderedScene scene = prepare_field(records, field, kernels, options, window, source);
    draw_whole(scene, options);
    return scene;
}

void draw_whole(RenderedScene& scene, const SceneOptions& options) {
    const auto t_paint = Clock::now();
    scene.image = paint(scene.objects, scene.window, options, &scene.clipped);
    scene.paint_seconds = seconds_since(t_paint);
    const auto t_noise = Clock::now();
    add_noise(scene.image, scene.window, scene.field.nx, options);
    scene.noise_seconds = seconds_since(t_noise);
}

long default_strip_rows(long width) {
    // About 1 M pixels (8 MB of doubles) a strip: reused memory instead of fresh pages, few
    // objects cut by a strip's edge (each such stamp is rendered once per strip it touches),
    // and on two threads a short wait for the last strip (2 M pixels: the HDF scene took
    // 0.27 s on two threads, 0.24 s now; 0.5 M: no faster).
    return std::max(64L, (1L << 20) / std::max(1L, width));
}

void draw_in_strips(RenderedScene& scene, const SceneOptions& options, long strip_rows,
                    const StripSink& sink) {
    const Tile& window = scene.window;
    const long ny = window.y1 - window.y0 + 1;
    require(strip_rows > 0 && ny > 0, "draw_in_strips: no rows");
    const long strips = (ny + strip_rows - 1) / strip_rows;
    // Threads share the strips, one strip each; a strip is then painted on one thread.
    SceneOptions one = options;
    one.threads = 1;
    struct Strip {
        ImageArray image;
        std::vector<ClippedLight> clipped;
        double paint_seconds, noise_seconds;
    };
    double sink_seconds = 0.0;
    // Strip images written out are painted over again: fresh ones would cost the kernel's
    // page faults and zeroing of 16 MB a strip.
    std::vector<ImageArray> spare;
    std::mutex spare_lock;
    parallel_in_order(
        std::size_t(strips), options.threads,
        [&](std::size_t k) {
            const long first = long(k) * strip_rows, last = std::min(ny, first + strip_rows);
            const Tile part{window.x0, window.y0 + first, window.x1, window.y0 + last - 1};
            Strip strip;
            {
                const std::lock_guard<std::mutex> hold(spare_lock);
                if (!spare.empty()) {
                    strip.image = std::move(spare.back());
                    spare.pop_back();
                }
            }
            const auto t_paint = Clock::now();
            paint_into(strip.image, scene.objects, part, one, &strip.clipped);
            strip.paint_seconds = seconds_since(t_paint);
            const auto t_noise = Clock::now();
            add_noise(strip.image, part, scene.field.nx, one);
            strip.noise_seconds = seconds_since(t_noise);
            return strip;
        },
        [&](std::size_t k, Strip&& strip) {
            const auto t_sink = Clock::now();
            sink(long(k) * strip_rows, strip.image);
            sink_seconds += seconds_since(t_sink);
            // Each strip a stamp reaches reports its whole stamp's clipped light: the same.
            for (std::size_t i = 0; i < strip.clipped.size(); ++i)
                if (strip.clipped[i].flux != 0.0 || strip.clipped[i].deepest != 0.0)
                    scene.clipped[i] = strip.clipped[i];
            scene.paint_seconds += strip.paint_seconds;
            scene.noise_seconds += strip.noise_seconds;
            const std::lock_guard<std::mutex> hold(spare_lock);
            spare.push_back(std::move(strip.image));
        });
    scene.sink_seconds = sink_seconds;
}

}  // namespace shapesim
