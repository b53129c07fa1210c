#pragma once
// "1,30,300" -> the frames at which compare and study report, sorted,
// duplicates dropped.
#include <string>
#include <vector>

namespace incise {

// Throws incise::Error("COMMAND: --frames must be ...") for an empty item, a
// non-number, or a frame outside 1..1000000.
std::vector<int> parse_frame_list(const std::string& text, const std::string& command);

}  // namespace incise
