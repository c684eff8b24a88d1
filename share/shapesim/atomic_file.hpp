// Atomic output files: a program never leaves a half-written output (DESIGN §1, STYLE (b)).
//
// An output `<name>` is written to `<name>.tmp.<pid>` beside it (same directory, so the final
// rename(2) is atomic on POSIX file systems) and renamed onto `<name>` by commit(). If commit()
// is never reached — an exception, an early return — the destructor unlinks the temporary, so
// the target is either absent/untouched or complete. (A process killed by a signal can still
// leave `*.tmp.<pid>` behind; .gitignore and `make clean` know the pattern.)
//
// A target that exists and is not a regular file (/dev/null, a FIFO) is written in place:
// renaming onto it would replace the device with a file. A symbolic link is written through:
// the file it points to is replaced (its temporary beside that file), the link kept.
//
// `check_writable` lets a program refuse an unwritable output before doing any work.
#pragma once

#include <fstream>
#include <iosfwd>
#include <memory>
#include <string>

namespace shapesim {

/// Throw Error unless `path` can be created or replaced: its directory exists and is
/// writable, and `path` is not a directory. Call before any work (Gnuastro's
/// `gal_checkset_writable_remove`); creates nothing.
void check_writable(const std::string& path);

/// On SIGINT, SIGTERM and SIGHUP (Ctrl-C, `timeout`, Slurm's preemption, a closed terminal):
/// remove every temporary of this process not yet committed, print `program: terminated;
/// unfinished outputs removed`, and die of the signal (the conventional exit status).
void remove_temporaries_on_signals(const std::string& program);

/// A temporary name `<target>.tmp.<pid>` that becomes `target` on commit().
/// The caller (e.g. cfitsio) creates and writes the temporary file itself.
class AtomicFile {
public:
    /// @param target final path of the output
    explicit AtomicFile(std::string target);
    /// Unlinks the temporary unless committed.
    ~AtomicFile();
    AtomicFile(const AtomicFile&) = delete;
    AtomicFile& operator=(const AtomicFile&) = delete;

    const std::string& target() const { return target_; }
    const std::string& temp_path() const { return temp_; }
    bool committed() const { return committed_; }
    /// The target is a device or a pipe (/dev/null, a FIFO): written in place, never renamed
    /// onto or removed (temp_path() is the target).
    bool direct() const { return direct_; }

    /// Rename the temporary onto the target; throws Error (naming the target) on failure.
    void commit();
    /// Remove the temporary now (no error if it does not exist).
    void discard() noexcept;

private:
    std::string target_, destination_;  ///< as named; that file through symbolic links
    bool direct_ = false;
    std::string temp_;
    int slot_ = -1;  ///< its place among the temporaries a signal removes
    bool committed_ = false;
};

/// A text output stream with AtomicFile semantics. The target "-" means stdout: then nothing
/// is renamed and commit() only flushes and checks the stream.
class AtomicTextFile {
public:
    /// Opens `<target>.tmp.<pid>` for writing (or stdout for "-"); throws Error on failure.
    explicit AtomicTextFile(const std::string& target);
    ~AtomicTextFile();

    /// The stream to write to.
    std::ostream& stream();
    /// The target's name for messages ("-" for stdout).
    const std::string& name() const { return name_; }
    /// Flush and close, check for write errors, rename onto the target. Throws Error.
    void commit();

private:
    std::string name_;
    std::unique_ptr<AtomicFile> file_;  // null for stdout
    std::ofstream out_;
};

}  // namespace shapesim
