// decompose_job.hpp: a record read into a job (its stamp, typed fields, PSF at its pixel
// scale, forced noise correlation), the job fitted as decompose() and shapelet_record() fit it,
// bright_star, errors kept in the outcome, and the fit's data/model/residual images.
#include "shapesim/decompose_job.hpp"

#include "shapesim/error.hpp"
#include "shapesim/fits_io.hpp"
#include "shapesim/jsonl.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <sstream>

using namespace shapesim;
namespace fs = std::filesystem;

namespace {

class DecomposeJobTest : public ::testing::Test {
protected:
    static constexpr int side = 31;
    static constexpr double sigma = 0.01;

    void SetUp() override {
        char pattern[] = "/tmp/shapesim-job-XXXXXX";
        ASSERT_NE(mkdtemp(pattern), nullptr);
        dir_ = pattern;
        truth_ = test::centred_galaxy(4, 2.5, side, 5, 50.0);
        stamp_.id = "17";
        stamp_.image = test::noisy_stamp(truth_, side, sigma, 5, 17);
        stamp_.weight = ImageArray::Constant(side, side, 1.0 / (sigma * sigma));
        stamp_.mask = ImageArray::Zero(side, side);
        stamp_.x0 = 101;
        stamp_.y0 = 201;
        FitsWriter out(stamps(), "test");
        write_stamp(out, stamp_);
        out.commit();
    }
    void TearDown() override { fs::remove_all(dir_); }
    std::string stamps() const { return dir_ + "/stamps.fits"; }

    // The source of the stamp, as shapesim-detect writes it.
    SourceRecord source() const {
        SourceRecord s;
        s.id = "17";
        s.x = truth_.x + 100;
        s.y = truth_.y + 200;
        s.flux = 49.0;
        s.a = 2.5;
        s.extra["stamp_file"] = stamps();
        s.extra["stamp_hdu"] = "17";
        s.extra["pixel_scale"] = 0.04;
        s.extra["zero_point"] = 25.0;
        s.extra["noise_correlation"] = 1.5;
        return s;
    }
    // The job of `record` read through a JsonlReader, as the program reads it.
    static DecomposeJob read_job(JobReader& jobs, const Json& record) {
        std::istringstream in(record.dump() + "\n");
        JsonlReader reader(in, "sources.jsonl", {SourceRecord::schema});
        SourceRecord s;
        EXPECT_TRUE(reader.next_record(s));
        return jobs.read(s, reader);
    }

    std::string dir_;
    ShapeletModel truth_;
    Stamp stamp_;
};

}  // namespace

TEST(DecomposeJob, BetaStartIsTheSemiMajorAxisAtLeastHalfAPixel) {
    SourceRecord s;
    EXPECT_EQ(beta_start(s), 1.0);
    s.a = 0.2;
    EXPECT_EQ(beta_start(s), 0.5);
    s.a = 3.25;
    EXPECT_EQ(beta_start(s), 3.25);
}

TEST_F(DecomposeJobTest, ReadsTheStampAndTheRecordsFields) {
    JobReader jobs{JobSettings{}};
    const DecomposeJob job = read_job(jobs, source().to_json());
    EXPECT_EQ(job.line, 1);
    EXPECT_EQ(job.source.id, "17");
    EXPECT_EQ(job.stamp.x0, 101);
    EXPECT_EQ(job.stamp.y0, 201);
    EXPECT_TRUE(job.stamp.image.isApprox(stamp_.image, 1e-6));
    EXPECT_EQ(job.pixel_scale, 0.04);
    ASSERT_TRUE(job.zero_point);
    EXPECT_EQ(*job.zero_point, 25.0);
    EXPECT_EQ(job.noise_correlation, 1.5);
    EXPECT_FALSE(job.forced_noise_correlation);
    EXPECT_FALSE(job.psf);
    EXPECT_TRUE(job.joint.bands.empty());

    // A forced factor replaces the record's; --white-noise is 1 unless one is forced.
    JobSettings forced;
    forced.noise_correlation = 2.0;
    forced.white_noise = true;
    JobReader forced_jobs(forced);
    const DecomposeJob f = read_job(forced_jobs, source().to_json());
    EXPECT_EQ(f.noise_correlation, 2.0);
    EXPECT_EQ(f.forced_noise_correlation, 2.0);
    JobSettings white;
    white.white_noise = true;
    JobReader white_jobs(white);
    const DecomposeJob w = read_job(white_jobs, source().to_json());
    EXPECT_EQ(w.noise_correlation, 1.0);
    EXPECT_EQ(w.forced_noise_correlation, 1.0);
}

TEST_F(DecomposeJobTest, ThePsfIsDilatedToTheRecordsPixelScale) {
    ShapeletModel psf(0.0, 0.0, 0.1, 0);  // β 0.1 arcsec
    psf.coeffs[0] = 1.0;
    JobReader jobs{JobSettings{}};
    jobs.set_psf(psf);
    const DecomposeJob job = read_job(jobs, source().to_json());
    ASSERT_TRUE(job.psf);
    EXPECT_NEAR(job.psf->beta_pix, 0.1 / 0.04, 1e-12);
}

TEST_F(DecomposeJobTest, BadFieldsArePlacedAtTheRecordsLine) {
    JobReader jobs{JobSettings{}};
    Json no_file = source().to_json();
    no_file.erase("stamp_file");
    EXPECT_THROW(read_job(jobs, no_file), Error);
    Json bad_scale = source().to_json();
    bad_scale["pixel_scale"] = "a";
    try {
        read_job(jobs, bad_scale);
        FAIL() << "a string pixel_scale was accepted";
    } catch (const Error& e) {
        EXPECT_EQ(e.file(), "sources.jsonl");
        EXPECT_EQ(e.line(), 1);
        EXPECT_EQ(e.field(), "pixel_scale");
    }
    // With --stamps no stamp_file is needed.
    JobSettings given;
    given.stamps = stamps();
    JobReader given_jobs(given);
    EXPECT_EQ(read_job(given_jobs, no_file).stamp.x0, 101);
    // A missing --stamps file is an error as soon as the reader is made.
    JobSettings missing;
    missing.stamps = dir_ + "/missing.fits";
    EXPECT_THROW(JobReader{missing}, Error);
}

TEST_F(DecomposeJobTest, AJobIsDecomposeAndItsRecord) {
    JobReader jobs{JobSettings{}};
    const DecomposeJob job = read_job(jobs, source().to_json());
    const DecomposeOutcome o = decompose_job(job, DecomposeOptions{}, {});
    ASSERT_TRUE(o.error.empty()) << o.error;
    ASSERT_TRUE(o.record && o.decomposition);

    DecomposeOptions fit;
    fit.noise_correlation = 1.5;
    MaskArray mask = MaskArray::Zero(side, side);
    // The detection's centre in the stamp, as the job computes it.
    const double x = job.source.x - (job.stamp.x0 - 1), y = job.source.y - (job.stamp.y0 - 1);
    const Decomposition d =
        decompose(job.stamp.image, job.stamp.weight, &mask, x, y, beta_start(job.source), fit);
    const ShapeletRecord r = shapelet_record(job.source, d, job.stamp, 0.04, 25.0);
    EXPECT_EQ(o.record->to_json().dump(), r.to_json().dump());
    EXPECT_EQ(std::count(o.record->flags.begin(), o.record->flags.end(), "bright_star"), 0);

    // A brighter star next to it flags it bright_star.
    SourceRecord star;
    star.id = "s1";
    star.x = o.record->x + 3.0;
    star.y = o.record->y;
    star.flux = 1e6;
    star.a = 2.0;
    star.extra["kron_radius"] = 3.5;
    const DecomposeOutcome starred = decompose_job(job, DecomposeOptions{}, {star});
    ASSERT_TRUE(starred.record);
    EXPECT_EQ(starred.record->flags.back(), "bright_star");
}

TEST_F(DecomposeJobTest, AnUnfittableStampIsTheOutcomesError) {
    JobReader jobs{JobSettings{}};
    DecomposeJob job = read_job(jobs, source().to_json());
    job.stamp.weight.setZero();
    DecomposeOutcome o;
    EXPECT_NO_THROW(o = decompose_job(job, DecomposeOptions{}, {}));
    EXPECT_FALSE(o.record);
    EXPECT_FALSE(o.error.empty());
}

TEST_F(DecomposeJobTest, FitImagesAreDataModelAndResidual) {
    JobReader jobs{JobSettings{}};
    const DecomposeJob job = read_job(jobs, source().to_json());
    const DecomposeOutcome o = decompose_job(job, DecomposeOptions{}, {});
    ASSERT_TRUE(o.decomposition);
    const std::string path = dir_ + "/models.fits";
    {
        FitsWriter out(path, "test");
        write_fit_images(out, job, o.decomposition->fit);
        out.commit();
    }
    FitsReader in(path);
    const ShapeletFit& fit = o.decomposition->fit;
    // BITPIX −32: float precision; LTV1/2 place the stamp in the parent image.
    const auto plane = [&](const std::string& name) {
        in.move_to(name);
        return in.read_image();
    };
    EXPECT_TRUE(plane("17.data").isApprox(job.stamp.image, 1e-6));
    EXPECT_TRUE(plane("17.model").isApprox(fit.model_image, 1e-6));
    EXPECT_TRUE(plane("17.residual").isApprox(fit.residual, 1e-5));
    in.move_to("17.model");
    EXPECT_EQ(in.optional_double("LTV1"), -100.0);
    EXPECT_EQ(in.optional_double("LTV2"), -200.0);
    EXPECT_EQ(in.list_hdus().size(), 4u);  // the primary and the three planes
}
