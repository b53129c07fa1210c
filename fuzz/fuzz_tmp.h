#pragma once
// A private folder for harnesses whose reader takes a path: under /dev/shm
// (else $TMPDIR or /tmp), named PREFIX.PID, emptied of FILES and removed at
// exit; folders of earlier runs that crashed (no atexit) and whose process is
// gone are removed first. Header-only: each target includes it once.
#include <dirent.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

namespace fuzz_tmp {

inline std::string g_dir;
inline std::vector<std::string> g_files;

inline void remove_files(const std::string& dir) {
  for (const std::string& f : g_files) std::remove((dir + "/" + f).c_str());
  rmdir(dir.c_str());
}

// files: the names the harness writes in the folder.
inline void init(const std::string& prefix, std::vector<std::string> files) {
  g_files = std::move(files);
  const char* tmp = std::getenv("TMPDIR");
  const std::string base = access("/dev/shm", W_OK) == 0 ? "/dev/shm" : tmp ? tmp : "/tmp";
  if (DIR* d = opendir(base.c_str())) {
    while (const dirent* e = readdir(d)) {
      const std::string name = e->d_name;
      if (name.rfind(prefix, 0) != 0) continue;
      const long pid = std::strtol(name.c_str() + prefix.size(), nullptr, 10);
      if (pid > 0 && kill(static_cast<pid_t>(pid), 0) != 0 && errno == ESRCH) remove_files(base + "/" + name);
    }
    closedir(d);
  }
  g_dir = base + "/" + prefix + std::to_string(getpid());
  if (mkdir(g_dir.c_str(), 0700) != 0 && errno != EEXIST) {
    std::perror(("mkdir " + g_dir).c_str());
    std::abort();
  }
  std::atexit([] { remove_files(g_dir); });
}

// Writes data to FOLDER/name and returns the path.
inline std::string put(const std::string& name, const void* data, size_t n) {
  const std::string path = g_dir + "/" + name;
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f || std::fwrite(data, 1, n, f) != n || std::fclose(f) != 0) {
    std::perror(path.c_str());
    std::abort();  // the harness's fault, not the reader's
  }
  return path;
}

}  // namespace fuzz_tmp
