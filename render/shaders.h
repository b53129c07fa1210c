#pragma once
// The one shading program: flat colour per draw, Lambert + ambient from a
// directional light, two-sided (a back face is lit with its flipped normal).
// Deliberately simple so llvmpipe and GPU drivers produce the same picture.
namespace incise {

// Compiles and links the program; throws incise::Error with the GL info log.
// Attribute locations: 0 = position, 1 = normal.
unsigned build_shading_program();

}  // namespace incise
