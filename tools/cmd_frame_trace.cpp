#include <cstdio>
#include <sstream>
#include <string>

#include "engine/util/file_io.h"
#include "tools/frame_trace.h"

namespace incise {

void write_frame_trace(const std::string& path, const std::vector<FrameTiming>& frames, int first_frame) {
  std::ostringstream os;
  {
    os << "frame,frame_ms,cut_frame";
    for (const char* s : kStageNames) os << ',' << s << "_ms";
    for (std::string p : kCutPartNames) {
      p = p.substr(p.find_first_not_of(' '));
      for (char& c : p) c = c == ' ' ? '_' : c;
      os << ",cut_" << p << "_ms";
    }
    os << ",newton,cg_iterations,substitutions,rescues,converged,factor_age,patch_dofs,tangent_updates,cg_start_residual,cpu_ms,substitution_ms,takeovers,"
          "contacts,grasp_rows,pgs_sweeps,max_depth,contact_force,bvh_rebuilds,budget_spent,cg_residual,inverted_points,rotation_change,rotation_rms,rotation_above,condensed_dofs,compliance_columns,line_search_halvings,recovery,newton_capped,swept_rows,speculative_rows,held_rows_dropped,assembly_workers\n";
    char buf[32];
    const auto num = [&](double v) {
      std::snprintf(buf, sizeof buf, "%.3f", v);
      return buf;
    };
    for (size_t k = 0; k < frames.size(); ++k) {
      const FrameTiming& t = frames[k];
      os << first_frame + static_cast<int>(k) << ',' << num(t.frame_ms) << ',' << (t.cut_frame ? 1 : 0);
      for (double v : t.ms) os << ',' << num(v);
      for (double v : t.cut_ms) os << ',' << num(v);
      os << ',' << t.newton << ',' << t.iterations << ',' << t.solves << ',' << t.rescues << ','
         << (t.converged ? 1 : 0) << ',' << t.factor_age << ',' << t.patch_dofs << ',' << t.tangent_updates << ',' << t.start_residual << ','
         << num(t.cpu_ms) << ',' << num(t.solve_kernel_ms) << ',' << t.takeovers << ',' << t.contacts << ','
         << t.grasp_rows << ',' << t.contact_sweeps << ',' << t.max_depth << ',' << t.contact_force << ','
         << t.bvh_rebuilds << ',' << (t.budget_spent ? 1 : 0) << ',' << t.residual << ','
         << t.inverted_points << ',' << t.rotation_change << ',' << t.rotation_rms << ',' << t.rotation_above << ',' << t.condensed_dofs << ',' << t.compliance_columns << ','
         << t.line_search_halvings << ',' << (t.recovery ? 1 : 0) << ',' << (t.newton_capped ? 1 : 0) << ',' << t.swept_rows << ',' << t.speculative_rows << ',' << t.held_rows_dropped << ',' << t.assembly_workers << '\n';
    }
  }
  write_file_atomic(path, os.str());
}

}  // namespace incise
