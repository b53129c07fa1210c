#include "tools/build_info.h"

#include <dlfcn.h>

#include <EGL/egl.h>
#include <cholmod.h>
#include <fcl/config.h>

#include <filesystem>
#include <fstream>
#include <sstream>

extern "C" void dgemm_(...);  // resolved to the BLAS library CHOLMOD uses (its path, not a call)

namespace incise {

std::string engine_version() { return INCISE_VERSION; }

std::string build_flags() {
  std::string s = std::string(INCISE_BUILD_TYPE) + " " + INCISE_COMPILER;
  if (INCISE_BUILD_NATIVE) s += " -march=native";
  if (INCISE_BUILD_SANITIZE) s += " asan+ubsan";
  return s;
}

std::string machine_name() {
  std::ifstream is("/proc/cpuinfo");
  std::string line;
  while (std::getline(is, line))
    if (line.rfind("model name", 0) == 0 && line.find(':') != std::string::npos)
      return line.substr(line.find(':') + 2);
  return "unknown CPU";
}

std::string version_report() {
  std::ostringstream os;
  os << "incise " << engine_version() << "\n";
  os << "build: " << build_flags() << "\n";
  os << "CHOLMOD " << CHOLMOD_MAIN_VERSION << "." << CHOLMOD_SUB_VERSION << "." << CHOLMOD_SUBSUB_VERSION << " ("
     << CHOLMOD_DATE << ")\n";
  Dl_info info{};
  const bool blas = dladdr(reinterpret_cast<void*>(&dgemm_), &info) != 0 && info.dli_fname;
  std::string blas_path = blas ? info.dli_fname : "unknown";
  std::error_code ec;
  if (blas) {  // Debian's libblas.so.3 is an alternative: name the library behind it
    const std::filesystem::path real = std::filesystem::canonical(blas_path, ec);
    if (!ec && real.string() != blas_path) blas_path += " -> " + real.string();
  }
  os << "BLAS: " << blas_path << "\n";
  os << "FCL " << FCL_VERSION << "\n";
  const char* egl = eglQueryString(EGL_NO_DISPLAY, EGL_VERSION);  // the client library's (EGL 1.5)
  os << "EGL: " << (egl ? egl : "client version not reported") << "\n";
#ifdef INCISE_WITH_OPENIGTLINK
  os << "OpenIGTLink: yes (haptics.device \"openigtlink\")\n";
#else
  os << "OpenIGTLink: no (libopenigtlink-dev was not found at build time)\n";
#endif
  return os.str();
}

}  // namespace incise
