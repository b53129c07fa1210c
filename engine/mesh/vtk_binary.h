#pragma once
// The binary encodings of VTK XML DataArrays (.vtu): format="binary" (base64
// inline) and format="appended" (raw or base64 after <AppendedData>), each
// block a header (UInt32 or UInt64: the byte count, or for
// vtkZLibDataCompressor [nblocks, block size, last block size, compressed
// sizes...]) then the data, in the file's byte order (LittleEndian only).
// Used by the .vtu reader (mesh_read_vtk.cpp) and tested on meshio's and
// hand-made files (tests/engine/mesh/test_mesh_io.cpp).
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace incise::meshio {

// Base64 as VTK writes it: the header and the data of a block are encoded
// separately and concatenated, so '=' padding may end a 4-character group
// in the middle of the text (a standard decoder stops there). Whitespace is
// skipped. Throws incise::Error(context + ...) on a character outside the
// alphabet or a truncated group.
std::string decode_vtk_base64(std::string_view text, const std::string& context);

struct VtkBlockFormat {
  bool uint64_header = false;  // VTKFile header_type="UInt64" (else UInt32)
  bool zlib = false;           // VTKFile compressor="vtkZLibDataCompressor"
};

// The data bytes of one block starting at `in[pos]` (decoded bytes: the
// base64 text already decoded, or the raw appended section); advances pos
// past it. Checks every size against what is there; throws
// incise::Error(context + ...) naming the size that does not fit.
std::string read_vtk_block(std::string_view in, size_t& pos, const VtkBlockFormat& fmt, const std::string& context);

// An inline format="binary" DataArray's text: one block filling it exactly
// (header and data encoded together or separately).
std::string decode_inline_block(std::string_view text, const VtkBlockFormat& fmt, const std::string& context);

// Bytes of `type` (Int8 ... UInt64, Float32, Float64) as doubles / integers.
// Throws for another type name or a length not a multiple of its size.
std::vector<double> vtk_values_as_double(const std::string& bytes, const std::string& type, const std::string& context);
std::vector<long long> vtk_values_as_int(const std::string& bytes, const std::string& type, const std::string& context);

}  // namespace incise::meshio
