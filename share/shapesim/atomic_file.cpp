#include "shapesim/atomic_file.hpp"

#include "shapesim/error.hpp"

#include <atomic>
#include <cerrno>
#include <csignal>
#include <climits>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <sys/stat.h>
#include <unistd.h>

namespace shapesim {

namespace {
std::string directory_of(const std::string& path) {
    const auto slash = path.find_last_of('/');
    if (slash == std::string::npos) return ".";
    return slash == 0 ? "/" : path.substr(0, slash);
}

std::string errno_text(int err) { return std::strerror(err); }
}  // namespace

void check_writable(const std::string& path) {
    if (path.empty()) throw Error("output file name is empty");
    struct stat st;
    if (stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode))
        throw Error("cannot write: is a directory", path);
    // A device or a pipe (/dev/null, a FIFO) is written in place: it must be writable itself.
    if (stat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode)) {
        if (access(path.c_str(), W_OK) != 0)
            throw Error("cannot write: " + errno_text(errno), path);
        return;
    }
    // The temporary is created, and renamed, in the target's directory: that is what must be
    // writable (a read-only existing target can still be replaced, as with `mv`).
    const std::string dir = directory_of(path);
    if (stat(dir.c_str(), &st) != 0)
        throw Error("cannot write: directory " + dir + ": " + errno_text(errno), path);
    if (!S_ISDIR(st.st_mode)) throw Error("cannot write: " + dir + " is not a directory", path);
    if (access(dir.c_str(), W_OK | X_OK) != 0)
        throw Error("cannot write: directory " + dir + ": " + errno_text(errno), path);
}

namespace {
// An existing target that is not a regular file (a character device such as /dev/null, a
// FIFO): renaming a temporary onto it would replace the device with a file.
bool is_special(const std::string& path) {
    struct stat st;
    return stat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode) && !S_ISDIR(st.st_mode);
}

// The file a path names, through symbolic links: a link's target is replaced, the link kept
// (as `cp` and shell redirection write through one). A dangling link names where it points.
std::string through_links(const std::string& path) {
    std::string p = path;
    for (int hops = 0; hops < 40; ++hops) {
        struct stat st;
        if (lstat(p.c_str(), &st) != 0 || !S_ISLNK(st.st_mode)) return p;
        std::string to(PATH_MAX, '\0');
        const ssize_t n = readlink(p.c_str(), to.data(), to.size());
        if (n <= 0) return p;
        to.resize(std::size_t(n));
        p = to[0] == '/' ? to : directory_of(p) + "/" + to;
    }
    return p;  // a loop of links: open() will say so
}
}  // namespace

// The temporaries alive in this process, for the signal handler: fixed slots of path text
// (an async-signal-safe handler may only read them and unlink), claimed with an atomic flag.
namespace {
constexpr int temporary_slots = 64;
struct TemporarySlot {
    std::atomic<int> state{0};  // 0 free, 1 being written, 2 live
    char path[PATH_MAX];
};
TemporarySlot temporaries[temporary_slots];
std::string signal_program;  // set once before the handlers are installed

int register_temporary(const std::string& path) {
    if (path.size() >= PATH_MAX) return -1;
    for (int k = 0; k < temporary_slots; ++k) {
        int expected = 0;
        if (temporaries[k].state.compare_exchange_strong(expected, 1)) {
            std::memcpy(temporaries[k].path, path.c_str(), path.size() + 1);
            temporaries[k].state.store(2);
            return k;
        }
    }
    return -1;  // more than 64 at once: that one is not removed on a signal
}

void unregister_temporary(int slot) {
    if (slot >= 0) temporaries[slot].state.store(0);
}

extern "C" void remove_temporaries_and_die(int signal) {
    for (TemporarySlot& t : temporaries)
        if (t.state.load() == 2) unlink(t.path);
    // One line, then the signal's own death (the exit status shells and Slurm expect).
    const char* name = signal == SIGINT   ? "interrupted"
                       : signal == SIGHUP ? "hung up"
                                          : "terminated";
    const std::string& p = signal_program;
    if (write(STDERR_FILENO, p.data(), p.size()) < 0 ||
        write(STDERR_FILENO, ": ", 2) < 0 || write(STDERR_FILENO, name, std::strlen(name)) < 0 ||
        write(STDERR_FILENO, "; unfinished outputs removed\n", 29) < 0) {
    }
    std::signal(signal, SIG_DFL);
    raise(signal);
}
}  // namespace

void remove_temporaries_on_signals(const std::string& program) {
    signal_program = program;
    for (int s : {SIGINT, SIGTERM, SIGHUP}) {
        struct sigaction action {};
        action.sa_handler = remove_temporaries_and_die;
        sigemptyset(&action.sa_mask);
        sigaction(s, &action, nullptr);
    }
}

AtomicFile::AtomicFile(std::string target)
    : target_(std::move(target)), destination_(through_links(target_)),
      direct_(is_special(destination_)),
      temp_(direct_ ? destination_ : destination_ + ".tmp." + std::to_string(getpid())),
      slot_(direct_ ? -1 : register_temporary(temp_)) {}

AtomicFile::~AtomicFile() {
    if (!committed_) discard();
}

void AtomicFile::commit() {
    if (committed_) return;
    if (direct_) {
        committed_ = true;
        return;
    }
    unregister_temporary(slot_);  // renamed, it is the output: a signal now leaves it
    slot_ = -1;
    if (std::rename(temp_.c_str(), destination_.c_str()) != 0) {
        const int err = errno;
        discard();
        throw Error("cannot rename " + temp_ + " to the output: " + errno_text(err), target_);
    }
    committed_ = true;
}

void AtomicFile::discard() noexcept {
    if (!direct_) std::remove(temp_.c_str());
    unregister_temporary(slot_);
    slot_ = -1;
}

AtomicTextFile::AtomicTextFile(const std::string& target) : name_(target) {
    if (target == "-") return;
    file_ = std::make_unique<AtomicFile>(target);
    out_.open(file_->temp_path(), std::ios::out | std::ios::trunc | std::ios::binary);
    if (!out_) throw Error("cannot create " + file_->temp_path() + ": " + errno_text(errno), name_);
}

AtomicTextFile::~AtomicTextFile() {
    if (out_.is_open()) out_.close();  // before AtomicFile unlinks the temporary
}

std::ostream& AtomicTextFile::stream() {
    return file_ ? static_cast<std::ostream&>(out_) : std::cout;
}

void AtomicTextFile::commit() {
    std::ostream& out = stream();
    errno = 0;
    out.flush();
    if (file_) out_.close();
    if (!out) {
        const int err = errno;
        throw Error(std::string("write failed") + (err ? ": " + errno_text(err) : ""), name_);
    }
    if (file_) file_->commit();
}

}  // namespace shapesim
