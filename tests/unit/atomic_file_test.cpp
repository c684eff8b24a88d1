// atomic_file: outputs appear whole or not at all; unwritable outputs fail before work.
#include "shapesim/atomic_file.hpp"
#include "shapesim/error.hpp"
#include "shapesim/fits_io.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <sys/stat.h>
#include <thread>
#include <unistd.h>

using namespace shapesim;
namespace fs = std::filesystem;

namespace {
class AtomicFileTest : public ::testing::Test {
protected:
    void SetUp() override {
        char pattern[] = "/tmp/shapesim-atomic-XXXXXX";
        ASSERT_NE(mkdtemp(pattern), nullptr);
        dir_ = pattern;
    }
    void TearDown() override { fs::remove_all(dir_); }
    std::string path(const std::string& name) const { return dir_ + "/" + name; }
    static std::string slurp(const std::string& p) {
        std::ifstream in(p);
        std::stringstream s;
        s << in.rdbuf();
        return s.str();
    }
    std::string dir_;
};
}  // namespace

TEST_F(AtomicFileTest, TempNameIsBesideTheTarget) {
    AtomicFile file(path("out.fits"));
    EXPECT_EQ(file.temp_path(), path("out.fits") + ".tmp." + std::to_string(getpid()));
    EXPECT_FALSE(file.committed());
}

TEST_F(AtomicFileTest, CommitRenamesOntoTarget) {
    {
        AtomicFile file(path("out.txt"));
        std::ofstream(file.temp_path()) << "complete\n";
        EXPECT_FALSE(fs::exists(path("out.txt")));  // nothing at the target before commit
        file.commit();
        EXPECT_TRUE(file.committed());
    }
    EXPECT_EQ(slurp(path("out.txt")), "complete\n");
    EXPECT_EQ(std::distance(fs::directory_iterator(dir_), fs::directory_iterator()), 1);
}

TEST_F(AtomicFileTest, UncommittedTemporaryIsRemovedAndTargetKept) {
    std::ofstream(path("out.txt")) << "old\n";
    try {
        AtomicFile file(path("out.txt"));
        std::ofstream(file.temp_path()) << "half";
        throw std::runtime_error("failure mid-write");
    } catch (const std::runtime_error&) {
    }
    EXPECT_EQ(slurp(path("out.txt")), "old\n");
    EXPECT_EQ(std::distance(fs::directory_iterator(dir_), fs::directory_iterator()), 1);
}

TEST_F(AtomicFileTest, CommitWithoutTemporaryThrowsNamingTarget) {
    AtomicFile file(path("never.txt"));
    try {
        file.commit();
        FAIL() << "expected Error";
    } catch (const Error& e) {
        EXPECT_EQ(e.file(), path("never.txt"));
    }
}

TEST_F(AtomicFileTest, TextFileCommitsAndDiscards) {
    {
        AtomicTextFile out(path("a.jsonl"));
        out.stream() << "{}\n";
        out.commit();
    }
    EXPECT_EQ(slurp(path("a.jsonl")), "{}\n");
    {
        AtomicTextFile out(path("b.jsonl"));
        out.stream() << "{\"half\":";
    }  // no commit: as if an exception had unwound the program
    EXPECT_FALSE(fs::exists(path("b.jsonl")));
    EXPECT_EQ(std::distance(fs::directory_iterator(dir_), fs::directory_iterator()), 1);
}

TEST_F(AtomicFileTest, TextFileDashIsStdout) {
    AtomicTextFile out("-");
    EXPECT_EQ(&out.stream(), &std::cout);
    EXPECT_EQ(out.name(), "-");
    EXPECT_NO_THROW(out.commit());
}

TEST_F(AtomicFileTest, CheckWritable) {
    EXPECT_NO_THROW(check_writable(path("new.fits")));
    EXPECT_FALSE(fs::exists(path("new.fits")));  // checking creates nothing
    std::ofstream(path("old.fits")) << "x";
    EXPECT_NO_THROW(check_writable(path("old.fits")));
    EXPECT_NO_THROW(check_writable("relative-name-in-cwd.fits"));
    EXPECT_THROW(check_writable(dir_), Error);  // a directory
    EXPECT_THROW(check_writable(""), Error);
    try {
        check_writable(path("missing/out.fits"));
        FAIL() << "expected Error";
    } catch (const Error& e) {
        EXPECT_EQ(e.file(), path("missing/out.fits"));
        EXPECT_NE(e.message().find("No such file or directory"), std::string::npos) << e.what();
    }
    if (geteuid() != 0) {  // root may write anywhere
        fs::permissions(dir_, fs::perms::owner_read | fs::perms::owner_exec);
        EXPECT_THROW(check_writable(path("new.fits")), Error);
        fs::permissions(dir_, fs::perms::owner_all);
    }
}

// A pipe or device target (here a FIFO; /dev/null alike) is written in place: renaming a
// temporary onto it would have replaced the device with a regular file (as `-o /dev/null` did
// to a root machine's /dev/null). FITS outputs refuse such a target.
TEST_F(AtomicFileTest, PipeTargetIsWrittenInPlaceNotReplaced) {
    const std::string fifo = path("pipe");
    ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
    std::string got;
    std::thread reader([&] { got = slurp(fifo); });
    {
        check_writable(fifo);
        AtomicTextFile out(fifo);
        out.stream() << "records\n";
        out.commit();
    }
    reader.join();
    EXPECT_EQ(got, "records\n");
    struct stat st;
    ASSERT_EQ(stat(fifo.c_str(), &st), 0);
    EXPECT_TRUE(S_ISFIFO(st.st_mode));
    EXPECT_FALSE(fs::exists(fifo + ".tmp." + std::to_string(getpid())));
    try {
        FitsWriter fits(fifo, "test");
        FAIL() << "a FITS file written to a pipe";
    } catch (const Error& e) {
        EXPECT_NE(e.message().find("device or a pipe"), std::string::npos) << e.message();
    }
    ASSERT_EQ(stat(fifo.c_str(), &st), 0);
    EXPECT_TRUE(S_ISFIFO(st.st_mode));
}

// A symbolic link is written through: the file it names is replaced, the link stays a link
// (and a dangling link gets its file made where it points).
TEST_F(AtomicFileTest, SymlinkTargetIsWrittenThroughTheLink) {
    const std::string file = path("real.jsonl"), link = path("link.jsonl");
    std::ofstream(file) << "old\n";
    fs::create_symlink("real.jsonl", link);  // relative, as `ln -s` makes them
    {
        AtomicTextFile out(link);
        out.stream() << "new\n";
        out.commit();
    }
    EXPECT_TRUE(fs::is_symlink(link));
    EXPECT_EQ(slurp(file), "new\n");
    const std::string dangling = path("dangling.jsonl");
    fs::create_symlink(path("made.jsonl"), dangling);
    {
        AtomicTextFile out(dangling);
        out.stream() << "made\n";
        out.commit();
    }
    EXPECT_TRUE(fs::is_symlink(dangling));
    EXPECT_EQ(slurp(path("made.jsonl")), "made\n");
    EXPECT_EQ(std::distance(fs::directory_iterator(dir_), fs::directory_iterator{}), 4);
}
