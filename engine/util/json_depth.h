#pragma once
// A nesting limit for JSON text, checked before nlohmann parses it: its
// dump(), comparison and copy recurse once per level, so a document nested
// 100,000 arrays deep overflowed the stack (in the error message's dump).
// A scene nests fewer than 10 levels; replay META and study files fewer too.
#include <cstddef>
#include <string>

namespace incise {

inline constexpr int kMaxJsonDepth = 64;

// 0 when brackets ([ and {) outside strings nest at most max_depth deep,
// else the line (from 1) of the first bracket past the limit. A linear scan:
// it recurses nowhere.
size_t json_too_deep(const std::string& text, int max_depth = kMaxJsonDepth);

// Throws Error "WHERE:LINE: nested deeper than 64 levels" when brackets
// nest deeper than max_depth (json_too_deep).
void check_json_depth(const std::string& text, const std::string& where, int max_depth = kMaxJsonDepth);

}  // namespace incise
