#include "engine/util/json_depth.h"

#include "engine/util/error.h"

namespace incise {

size_t json_too_deep(const std::string& text, int max_depth) {
  int depth = 0;
  size_t line = 1;
  bool in_string = false, escaped = false;
  for (char c : text) {
    if (c == '\n') ++line;
    if (in_string) {
      if (escaped) escaped = false;
      else if (c == '\\') escaped = true;
      else if (c == '"') in_string = false;
    } else if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      if (++depth > max_depth) return line;
    } else if (c == ']' || c == '}') {
      if (depth > 0) --depth;  // unbalanced text is the parser's to report; "]]][[[" must not hide depth
    }
  }
  return 0;
}

void check_json_depth(const std::string& text, const std::string& where, int max_depth) {
  if (const size_t line = json_too_deep(text, max_depth))
    throw Error(where + ":" + std::to_string(line) + ": nested deeper than " + std::to_string(max_depth) +
                " levels of [ and {");
}

}  // namespace incise
