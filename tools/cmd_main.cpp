#include <iostream>

#include "tools/cli.h"

namespace incise {
int cli_main(int, char**) {
  std::cerr << "incise: not yet built\n";
  return 1;
}
}  // namespace incise
