#include "engine/util/file_io.h"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include "engine/util/error.h"

namespace incise {

namespace {

const char* kind_of(mode_t m) {
  if (S_ISDIR(m)) return "a directory";
  if (S_ISFIFO(m)) return "a FIFO";
  if (S_ISCHR(m)) return "a character device";
  if (S_ISBLK(m)) return "a block device";
  if (S_ISSOCK(m)) return "a socket";
  return "a special file";
}

std::string mib(std::size_t bytes) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.0f MiB", static_cast<double>(bytes) / (1 << 20));
  return buf;
}

// Checks the type and size of an open descriptor.
void check_stat(const struct stat& st, const std::string& path, std::size_t max_bytes, const char* what) {
  if (!S_ISREG(st.st_mode))
    throw Error(path + ": cannot read " + what + ": it is " + kind_of(st.st_mode) + ", not a regular file");
  if (static_cast<unsigned long long>(st.st_size) > max_bytes)
    throw Error(path + ": " + what + " is " + mib(static_cast<std::size_t>(st.st_size)) +
                ", more than the limit of " + mib(max_bytes) + " for such files");
}

// Opens without blocking (a FIFO without a writer would block in open()).
int open_checked(const std::string& path, std::size_t max_bytes, const char* what, struct stat& st) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) throw Error(path + ": cannot open " + what + ": " + std::strerror(errno));
  if (::fstat(fd, &st) != 0) {
    const int err = errno;
    ::close(fd);
    throw Error(path + ": cannot read " + what + ": " + std::strerror(err));
  }
  try {
    check_stat(st, path, max_bytes, what);
  } catch (...) {
    ::close(fd);
    throw;
  }
  return fd;
}

}  // namespace

std::string read_input_file(const std::string& path, std::size_t max_bytes, const char* what) {
  struct stat st;
  const int fd = open_checked(path, max_bytes, what, st);
  std::string text;
  try {
    text.resize(static_cast<std::size_t>(st.st_size));
  } catch (const std::bad_alloc&) {
    ::close(fd);
    throw Error(path + ": " + what + " does not fit in memory (" + mib(static_cast<std::size_t>(st.st_size)) + ")");
  }
  std::size_t got = 0;
  // The file may grow or shrink while read: take what is there, up to the limit.
  for (;;) {
    if (got == text.size()) {
      if (text.size() >= max_bytes) break;
      text.resize(std::min(max_bytes, text.size() + (std::size_t(1) << 16)));
    }
    const ssize_t n = ::read(fd, text.data() + got, text.size() - got);
    if (n < 0) {
      if (errno == EINTR) continue;
      const int err = errno;
      ::close(fd);
      throw Error(path + ": cannot read " + what + ": " + std::strerror(err));
    }
    if (n == 0) break;
    got += static_cast<std::size_t>(n);
  }
  ::close(fd);
  text.resize(got);
  // A UTF-8 byte order mark (spreadsheets write one before a CSV's header)
  // is not content: left in, it made "t,x,y,z,..." fail as a header that
  // printed exactly like the expected one.
  if (text.size() >= 3 && text.compare(0, 3, "\xEF\xBB\xBF") == 0) text.erase(0, 3);
  return text;
}

void check_input_file(const std::string& path, std::size_t max_bytes, const char* what) {
  struct stat st;
  ::close(open_checked(path, max_bytes, what, st));
}

void write_file_atomic(const std::string& path, const std::string& content) {
  const std::string tmp = path + ".tmp" + std::to_string(::getpid());
  std::FILE* fp = std::fopen(tmp.c_str(), "wb");
  if (!fp) {
    const int err = errno;
    struct stat st;
    if (::stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode)) throw Error(path + ": cannot write: it is a directory");
    throw Error(path + ": cannot write: " + std::strerror(err));
  }
  bool ok = std::fwrite(content.data(), 1, content.size(), fp) == content.size();
  int err = errno;
  if (std::fclose(fp) != 0 && ok) {
    ok = false;
    err = errno;
  }
  if (ok && std::rename(tmp.c_str(), path.c_str()) != 0) {
    ok = false;
    err = errno;
  }
  if (!ok) {
    std::remove(tmp.c_str());
    struct stat st;
    if (::stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode)) throw Error(path + ": cannot write: it is a directory");
    throw Error(path + ": cannot write: " + std::strerror(err));
  }
}

}  // namespace incise
