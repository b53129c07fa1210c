#include <filesystem>
#include <iostream>

#include "engine/util/error.h"
#include "engine/runtime/malloc_tuning.h"
#include "tools/build_info.h"
#include "tools/cli.h"
#include "tools/commands.h"
#include "tools/interrupt.h"

namespace incise {

int cli_main(int argc, char** argv) {
  tune_malloc_for_frames();  // engine/runtime/malloc_tuning.h: no page faults from rebuilt Models in cut frames
  CLI::App app{"incise: real-time surgical cutting engine (corotated tet10 FEM, Newmark, CHOLMOD)"};
  app.set_version_flag("--version", [] { return version_report(); }, "Print the version, build flags and libraries, and exit");
  app.require_subcommand(1);
  add_run_command(app);
  add_static_command(app);
  add_bench_command(app);
  add_mesh_command(app);
  add_compare_command(app);
  add_render_command(app);
  add_replay_command(app);
  add_study_command(app);
  try {
    app.parse(argc, argv);
    if (interrupt_signal()) return 128 + interrupt_signal();  // tools/interrupt.h: stopped early, outputs complete
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const Error& e) {
    std::cerr << "incise: error: " << e.what() << "\n";
    return 1;
  } catch (const std::filesystem::filesystem_error& e) {
    // An output folder that cannot be made (a file of that name, no
    // permission) is the user's to fix: "out: cannot create directories: Not a directory".
    std::string what = e.what();
    if (what.rfind("filesystem error: ", 0) == 0) what = what.substr(18);
    if (const size_t at = what.rfind(" ["); at != std::string::npos) what.resize(at);
    std::cerr << "incise: error: " << (e.path1().empty() ? "" : e.path1().string() + ": ") << what << "\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "incise: internal error: " << e.what() << "\n";
    return 2;
  }
  return 0;
}

}  // namespace incise
