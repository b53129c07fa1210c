#pragma once
// Reading user input files and writing outputs safely.
//
// Input: only regular files are read (a FIFO would block forever, a device
// like /dev/zero would be read until memory runs out), and only up to a size
// limit per kind of file; the error names the file, what it was expected to
// be and the limit. Output: written through a temporary file in the same
// folder and renamed into place, so a reader never sees a half-written file
// and a failed write leaves nothing behind.
#include <cstddef>
#include <string>

namespace incise {

// Size limits per kind of input (bytes). Generous for real data: a 2M-tet
// tet10 mesh in ASCII Gmsh is about 1 GB; the largest bundled scene is 5 KB.
inline constexpr std::size_t kMaxMeshBytes = std::size_t(4) << 30;      // 4 GiB
inline constexpr std::size_t kMaxSceneBytes = std::size_t(16) << 20;    // 16 MiB
inline constexpr std::size_t kMaxTableBytes = std::size_t(512) << 20;   // CSV, OBJ, STL: 512 MiB

// The whole content of `path`, which must be a regular file of at most
// max_bytes, without a leading UTF-8 byte order mark. `what` names the kind
// of file in messages ("mesh file").
// Throws Error: "PATH: cannot read WHAT: it is a FIFO, not a regular file".
std::string read_input_file(const std::string& path, std::size_t max_bytes, const char* what);

// Throws unless `path` names a regular file (what read_input_file checks,
// for readers that stream, e.g. through a library).
void check_input_file(const std::string& path, std::size_t max_bytes, const char* what);

// Writes content to path atomically (temporary file + rename). On failure
// the temporary file is removed and Error names the path and the reason,
// e.g. "out/run: cannot write: Is a directory".
void write_file_atomic(const std::string& path, const std::string& content);

}  // namespace incise
