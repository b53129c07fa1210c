#pragma once
// Each sub-command registers itself on the CLI11 app; its callback runs it.
#include <CLI/CLI.hpp>

namespace incise {

void add_run_command(CLI::App& app);     // incise run SCENE --frames N [--out DIR] [--render DIR]
void add_static_command(CLI::App& app);  // incise static SCENE [--probe P.csv] [--out R.csv]
void add_bench_command(CLI::App& app);    // incise bench SCENE --frames N [--json F] [--render]
void add_mesh_command(CLI::App& app);     // incise mesh beam|convert ...
void add_compare_command(CLI::App& app);  // incise compare SCENE [--policy P] [--frames 1,30,300]
void add_render_command(CLI::App& app);   // incise render SCENE --frame K --out F.png
void add_study_command(CLI::App& app);   // incise study SCENE --sweep K=V1,V2 ... | --point K | --collect DIR
void add_replay_command(CLI::App& app);   // incise replay F [--verify] [--tolerance T] [--out DIR] [--render DIR]

// --egl-platform auto|device|surfaceless (run, replay, bench, render).
void add_egl_platform_option(CLI::App& cmd, std::string& platform);

// Prints the model summary (DOFs, elements, factor) used by run/static/bench.
struct Simulation;
void print_model_summary(const Simulation& sim);

}  // namespace incise
