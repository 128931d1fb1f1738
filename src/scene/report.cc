// threshing_sim result writers: run summary (JSON and prose), state trace and event log (CSV).
#include "threshing_sim/scene/report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <utility>

#include "threshing_sim/core/simulator.h"

namespace threshing_sim {
namespace {

// Outcome totals over the kernels of a report (counts, and the largest forces [N]).
struct OutcomeTotals {
  long detached = 0, damaged = 0, fractured = 0, subs = 0, macros = 0;
  int max_subs = 0;
  double peak_normal_N = 0, peak_tangential_N = 0, max_contact_N = 0;
};

OutcomeTotals totalsOf(const OutcomeReport& report) {
  OutcomeTotals t;
  for (const KernelOutcome& o : report.kernels) {
    t.detached += o.detached ? 1 : 0;
    t.damaged += o.damage != DamageClass::kNone ? 1 : 0;
    t.fractured += o.damage == DamageClass::kFracture ? 1 : 0;
    t.macros += o.macro_collisions;
    t.subs += o.sub_collisions;
    t.max_subs = std::max(t.max_subs, o.max_sub_collisions);
    t.peak_normal_N = std::max(t.peak_normal_N, o.peak_normal_force_N);
    t.peak_tangential_N = std::max(t.peak_tangential_N, o.peak_tangential_force_N);
    t.max_contact_N = std::max(t.max_contact_N, o.max_contact_force_N);
  }
  return t;
}

// ---------------------------------------------------------------------------------------------
// Number and string formatting.

// Full precision, so that reruns can be compared bit for bit.
std::string exact(double value) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.17g", value);
  return text;
}

// Three significant digits with an SI prefix, e.g. "41.2 N", "3.4 um".
std::string readable(double value, const char* unit) {
  static const struct {
    double scale;
    const char* prefix;
  } kPrefixes[] = {{1e9, "G"},  {1e6, "M"},  {1e3, "k"},  {1, ""},
                   {1e-3, "m"}, {1e-6, "u"}, {1e-9, "n"}, {1e-12, "p"}};
  char text[64];
  if (value == 0 || !std::isfinite(value)) {
    std::snprintf(text, sizeof(text), "%g %s", value, unit);
    return text;
  }
  for (const auto& p : kPrefixes) {
    if (std::fabs(value) >= p.scale || p.scale == 1e-12) {
      std::snprintf(text, sizeof(text), "%.3g %s%s", value / p.scale, p.prefix, unit);
      break;
    }
  }
  return text;
}

std::string jsonString(const std::string& s) {
  std::string out = "\"";
  for (const char c : s) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char escape[8];
      std::snprintf(escape, sizeof(escape), "\\u%04x", static_cast<unsigned>(c));
      out += escape;
    } else {
      out += c;
    }
  }
  return out + "\"";
}

// ---------------------------------------------------------------------------------------------
// JSON objects: ordered key/value lists whose values are already JSON text.

using JsonFields = std::vector<std::pair<std::string, std::string>>;

// Builds the fields of one object; non-finite numbers become null and their keys are recorded.
class JsonBuilder {
 public:
  JsonBuilder(std::string key_prefix, std::vector<std::string>* non_finite)
      : prefix_(std::move(key_prefix)), non_finite_(non_finite) {}

  void number(const std::string& key, double value) {
    if (!std::isfinite(value)) non_finite_->push_back(prefix_ + key);
    fields_.emplace_back(key, std::isfinite(value) ? exact(value) : "null");
  }
  void integer(const std::string& key, long value) {
    fields_.emplace_back(key, std::to_string(value));
  }
  void boolean(const std::string& key, bool value) {
    fields_.emplace_back(key, value ? "true" : "false");
  }
  void vec2(const std::string& key, const Vec2& v) {
    const bool finite = v.allFinite();
    if (!finite) non_finite_->push_back(prefix_ + key);
    fields_.emplace_back(key, finite ? "[" + exact(v.x()) + ", " + exact(v.y()) + "]" : "null");
  }
  void raw(const std::string& key, const std::string& json) { fields_.emplace_back(key, json); }
  const JsonFields& fields() const { return fields_; }

 private:
  std::string prefix_;
  std::vector<std::string>* non_finite_;
  JsonFields fields_;
};

// One object, one field per line at the given indentation.
std::string jsonObject(const JsonFields& fields, int indent) {
  const std::string pad(indent + 2, ' ');
  std::string out = "{\n";
  for (size_t i = 0; i < fields.size(); ++i) {
    out += pad + jsonString(fields[i].first) + ": " + fields[i].second;
    out += i + 1 < fields.size() ? ",\n" : "\n";
  }
  return out + std::string(indent, ' ') + "}";
}

// A per-kernel statistic, or the fallback if the core did not size the vector.
template <typename T>
T perKernel(const std::vector<T>& values, size_t i, T fallback) {
  return i < values.size() ? values[i] : fallback;
}

// Final state and statistics of kernel i.
std::string kernelJson(const Model& model, const Data& data, int i,
                       std::vector<std::string>* non_finite) {
  const RunStats& s = data.stats;
  const int dof = model.kernels[i].dof_offset;
  JsonBuilder k("kernels." + std::to_string(i) + ".", non_finite);
  k.vec2("position_m", kernelPosition(model, data, i));
  k.number("angle_rad", kernelAngle(model, data, i));
  k.vec2("velocity_mps", data.u.segment<2>(dof));
  k.number("angular_velocity_radps", data.u[dof + 2]);
  k.number("peak_normal_force_N", perKernel(s.kernel_peak_normal_force_N, i, 0.0));
  k.integer("impacts", perKernel(s.kernel_impacts, i, 0L));
  const double detach_time_s = perKernel(s.kernel_detach_time_s, i, -1.0);
  k.boolean("detached", detach_time_s >= 0);
  if (detach_time_s >= 0) {
    k.number("detach_time_s", detach_time_s);
  } else {
    k.raw("detach_time_s", "null");
  }
  return jsonObject(k.fields(), 4);
}

// "1 tooth", "2 teeth".
std::string count(size_t n, const char* one, const char* many) {
  return std::to_string(n) + " " + (n == 1 ? one : many);
}

// A time that may be absent (< 0): the number, or null.
void optionalTime(JsonBuilder* j, const std::string& key, double t_s) {
  if (t_s >= 0) {
    j->number(key, t_s);
  } else {
    j->raw(key, "null");
  }
}

// The "outcomes" object: thresholds, totals over the kernels, then one object per kernel.
std::string outcomesJson(const OutcomeReport& report, std::vector<std::string>* non_finite) {
  JsonBuilder j("outcomes.", non_finite);
  j.number("plastic_force_N", report.thresholds.plastic_force_N);
  j.number("fracture_force_N", report.thresholds.fracture_force_N);
  j.number("sample_interval_s", report.sample_interval_s);

  // Totals.
  const OutcomeTotals tot = totalsOf(report);
  j.integer("kernels", static_cast<long>(report.kernels.size()));
  j.integer("detached", tot.detached);
  j.integer("damaged", tot.damaged);
  j.integer("fractured", tot.fractured);
  j.integer("macro_collisions", tot.macros);
  j.integer("sub_collisions", tot.subs);
  j.integer("max_sub_collisions", tot.max_subs);
  j.number("peak_normal_force_N", tot.peak_normal_N);
  j.number("peak_tangential_force_N", tot.peak_tangential_N);
  j.number("max_contact_force_N", tot.max_contact_N);

  // Per kernel.
  std::string items;
  for (size_t i = 0; i < report.kernels.size(); ++i) {
    const KernelOutcome& o = report.kernels[i];
    JsonBuilder k("outcomes.per_kernel." + std::to_string(i) + ".", non_finite);
    k.integer("kernel", static_cast<long>(i));
    k.number("peak_normal_force_N", o.peak_normal_force_N);
    optionalTime(&k, "time_of_peak_normal_s", o.time_of_peak_normal_s);
    k.number("peak_tangential_force_N", o.peak_tangential_force_N);
    optionalTime(&k, "time_of_peak_tangential_s", o.time_of_peak_tangential_s);
    if (o.time_of_peak_normal_s >= 0 && o.time_of_peak_tangential_s >= 0) {
      k.number("peak_separation_s", o.peak_separation_s);
    } else {
      k.raw("peak_separation_s", "null");
    }
    k.number("max_contact_force_N", o.max_contact_force_N);
    k.number("total_normal_impulse_Ns", o.total_normal_impulse_Ns);
    k.integer("impacts", o.impacts);
    k.integer("macro_collisions", o.macro_collisions);
    k.integer("sub_collisions", o.sub_collisions);
    k.number("sub_collisions_per_macro", o.subCollisionsPerMacro());
    k.integer("max_sub_collisions", o.max_sub_collisions);
    k.number("max_impact_energy_J", o.max_impact_energy_J);
    k.boolean("detached", o.detached);
    optionalTime(&k, "detach_time_s", o.detach_time_s);
    k.raw("damage", jsonString(toString(o.damage)));
    items += (i ? ",\n      " : "\n      ") + jsonObject(k.fields(), 6);
  }
  j.raw("per_kernel", "[" + items + (items.empty() ? "]" : "\n    ]"));
  return jsonObject(j.fields(), 2);
}

// Outcome totals as a sentence, then one line per kernel (up to kMaxKernelLines).
void printOutcomes(std::ostream& out, const OutcomeReport& report) {
  constexpr size_t kMaxKernelLines = 10;
  const OutcomeTotals tot = totalsOf(report);
  const long damaged = tot.damaged, fractured = tot.fractured, detached = tot.detached;
  const long macros = tot.macros, subs = tot.subs;
  out << "Outcomes: " << damaged << " of " << report.kernels.size() << " kernels damaged (contact "
      << "force >= " << readable(report.thresholds.plastic_force_N, "N") << "), " << fractured
      << " fractured (>= " << readable(report.thresholds.fracture_force_N, "N") << "), " << detached
      << " detached; " << count(macros, "tooth macro-collision", "tooth macro-collisions")
      << " holding " << count(subs, "sub-collision", "sub-collisions") << ".\n";
  for (size_t i = 0; i < report.kernels.size() && i < kMaxKernelLines; ++i) {
    const KernelOutcome& o = report.kernels[i];
    out << "  kernel " << i << ": tooth force peaks normal " << readable(o.peak_normal_force_N, "N")
        << ", tangential " << readable(o.peak_tangential_force_N, "N");
    if (o.time_of_peak_normal_s >= 0 && o.time_of_peak_tangential_s >= 0) {
      out << " (" << readable(o.peak_separation_s, "s") << " after the normal peak)";
    }
    out << ", max contact force " << readable(o.max_contact_force_N, "N") << ", impulse "
        << readable(o.total_normal_impulse_Ns, "N s") << ", "
        << count(o.impacts, "impact", "impacts") << ", "
        << count(o.macro_collisions, "macro-collision", "macro-collisions") << " / "
        << count(o.sub_collisions, "sub-collision", "sub-collisions") << ", max impact energy "
        << readable(o.max_impact_energy_J, "J") << ", "
        << (o.detached ? "detached at " + readable(o.detach_time_s, "s") : "attached")
        << ", damage " << toString(o.damage) << "\n";
  }
  if (report.kernels.size() > kMaxKernelLines) {
    out << "  (" << report.kernels.size() - kMaxKernelLines << " more kernels in --outcomes)\n";
  }
}

std::string joinList(const std::vector<std::string>& items) {
  std::string out;
  for (const std::string& item : items) out += (out.empty() ? "" : ", ") + item;
  return out;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Summary JSON.

std::string schedulerJson(const SchedulerStats& s) {
  const std::pair<const char*, long> fields[] = {{"windows", s.windows},
                                                 {"island_steps", s.island_steps},
                                                 {"island_body_steps", s.island_body_steps},
                                                 {"islands_built", s.islands_built},
                                                 {"islands_dissolved", s.islands_dissolved},
                                                 {"tooth_wakes", s.tooth_wakes},
                                                 {"kernel_wakes", s.kernel_wakes},
                                                 {"predictions", s.predictions},
                                                 {"shrinks", s.shrinks},
                                                 {"pedicel_steps", s.pedicel_steps},
                                                 {"pedicel_rejected", s.pedicel_rejected},
                                                 {"sleeps", s.sleeps},
                                                 {"asleep", s.asleep},
                                                 {"pedicel_breaks", s.pedicel_breaks},
                                                 {"free_advances", s.free_advances},
                                                 {"tooth_advances", s.tooth_advances}};
  std::string out = "{";
  for (const auto& f : fields)
    out += std::string(out.size() > 1 ? ", " : "") + "\"" + f.first +
           "\": " + std::to_string(f.second);
  return out + "}";
}

void writeSummaryJson(std::ostream& out, const Model& model, const Data& data,
                      const std::string& status, double wall_time_s, double energy_final_J,
                      const OutcomeReport* outcomes) {
  const RunStats& s = data.stats;
  std::vector<std::string> non_finite;

  // Run totals and peaks.
  JsonBuilder j("", &non_finite);
  j.number("sim_time_s", data.t_s);
  j.number("wall_time_s", wall_time_s);
  j.integer("steps", data.steps);
  j.integer("impacts", s.impacts);
  j.integer("contact_episodes", s.contact_episodes);
  j.number("peak_normal_force_N", s.peak_normal_force_N);
  j.number("peak_tangential_force_N", s.peak_tangential_force_N);
  j.number("time_of_peak_normal_s", s.time_of_peak_normal_s);
  j.number("time_of_peak_tangential_s", s.time_of_peak_tangential_s);
  j.number("total_normal_impulse_Ns", s.total_normal_impulse_Ns);
  j.number("max_penetration_m", s.max_penetration_m);

  // Energy balance and numerical health.
  j.number("max_energy_gain_at_impact_J", s.max_energy_gain_at_impact_J);
  j.number("energy_initial_J", s.energy_initial_J);
  j.number("energy_final_J", energy_final_J);
  j.number("drive_work_J", s.drive_work_J);
  j.integer("numerical_recoveries", s.numerical_recoveries);
  j.integer("rejected_steps", s.rejected_steps);
  j.integer("depth_corrections", s.depth_corrections);
  j.number("max_tip_deflection_ratio", s.max_tip_deflection_ratio);
  j.raw("scheduler", schedulerJson(s.scheduler));
  std::string warnings = "[";
  for (size_t i = 0; i < s.warnings.size(); ++i) {
    warnings += (i ? ", " : "") + jsonString(s.warnings[i]);
  }
  j.raw("warnings", warnings + "]");

  // Kernels.
  std::string kernels;
  for (size_t i = 0; i < model.kernels.size(); ++i) {
    kernels +=
        (i ? ",\n    " : "\n    ") + kernelJson(model, data, static_cast<int>(i), &non_finite);
  }
  j.raw("kernels", "[" + kernels + (kernels.empty() ? "]" : "\n  ]"));
  if (outcomes != nullptr) j.raw("outcomes", outcomesJson(*outcomes, &non_finite));

  // Status first; it names any value written as null.
  std::string full_status = status;
  if (!non_finite.empty()) {
    full_status += "; non-finite values written as null: " + joinList(non_finite);
  }
  JsonFields fields = {{"status", jsonString(full_status)}};
  fields.insert(fields.end(), j.fields().begin(), j.fields().end());
  out << jsonObject(fields, 0) << "\n";
}

// ---------------------------------------------------------------------------------------------
// Human-readable summary.

void printSummary(std::ostream& out, const Model& model, const Data& data,
                  const std::string& status, double wall_time_s, double energy_final_J,
                  const OutcomeReport* outcomes) {
  const RunStats& s = data.stats;
  const char* integrator =
      model.integrator.type == IntegratorType::kEventDriven ? "event-driven" : "time stepping";
  int detached = 0;
  for (const double t : s.kernel_detach_time_s) detached += t >= 0 ? 1 : 0;

  // Run, contacts, energy, kernels.
  out << "Simulated " << readable(data.t_s, "s") << " of "
      << count(model.teeth.size(), "tooth", "teeth") << " and "
      << count(model.kernels.size(), "kernel", "kernels") << " (" << integrator << ", "
      << data.steps << " steps) in " << readable(wall_time_s, "s") << " of wall time: " << status
      << ". " << count(s.impacts, "impact", "impacts") << " in "
      << count(s.contact_episodes, "contact episode", "contact episodes") << "; peak normal force "
      << readable(s.peak_normal_force_N, "N")
      << " at t = " << readable(s.time_of_peak_normal_s, "s") << ", peak tangential force "
      << readable(s.peak_tangential_force_N, "N")
      << " at t = " << readable(s.time_of_peak_tangential_s, "s") << "; total normal impulse "
      << readable(s.total_normal_impulse_Ns, "N s") << ", max penetration "
      << readable(s.max_penetration_m, "m") << ". Mechanical energy "
      << readable(s.energy_initial_J, "J") << " at start and " << readable(energy_final_J, "J")
      << " at end, drive work " << readable(s.drive_work_J, "J")
      << ", largest energy gain at an impact " << readable(s.max_energy_gain_at_impact_J, "J")
      << ". " << detached << " of " << model.kernels.size() << " kernels detached; "
      << count(s.numerical_recoveries, "numerical recovery", "numerical recoveries") << ".\n";
  if (outcomes != nullptr) printOutcomes(out, *outcomes);
  for (const std::string& w : s.warnings) out << "warning: " << w << "\n";
}

// ---------------------------------------------------------------------------------------------
// State trace CSV.

void writeTraceHeader(std::ostream& out, const Model& model) {
  out << "t_s,theta_rad,omega_radps";
  for (size_t i = 0; i < model.kernels.size(); ++i) {
    const std::string k = ",k" + std::to_string(i) + "_";
    out << k << "x_m" << k << "y_m" << k << "psi_rad" << k << "vx_mps" << k << "vy_mps" << k
        << "omega_radps";
  }
  for (size_t t = 0; t < model.teeth.size(); ++t) {
    const std::string tooth = ",tooth" + std::to_string(t) + "_";
    out << tooth << "tip_deflection_m";
    for (int j = 0; j < model.teeth[t].n_modes; ++j) out << tooth << "q" << j;
  }
  out << "\n";
}

void writeTraceRow(std::ostream& out, const Model& model, const Data& data) {
  out << exact(data.t_s) << "," << exact(data.theta_rad) << "," << exact(data.omega_radps);
  for (size_t i = 0; i < model.kernels.size(); ++i) {
    const int k = static_cast<int>(i);
    const int dof = model.kernels[i].dof_offset;
    const Vec2 c = kernelPosition(model, data, k);
    out << "," << exact(c.x()) << "," << exact(c.y()) << "," << exact(kernelAngle(model, data, k))
        << "," << exact(data.u[dof]) << "," << exact(data.u[dof + 1]) << ","
        << exact(data.u[dof + 2]);
  }
  for (size_t t = 0; t < model.teeth.size(); ++t) {
    const ToothModel& tooth = model.teeth[t];
    out << "," << exact(toothDeflection(model, data, static_cast<int>(t), tooth.length_m));
    for (int j = 0; j < tooth.n_modes; ++j) out << "," << exact(data.z[tooth.dof_offset + j]);
  }
  out << "\n";
}

// ---------------------------------------------------------------------------------------------
// Event log CSV.

void writeEventsHeader(std::ostream& out) {
  out << "t_s,kind,a,b,from,to,is_impact,vn_before_mps,vn_after_mps,vt_before_mps,vt_after_mps,"
         "impulse_normal_Ns,impulse_tangential_Ns,energy_lost_J,peak_normal_force_N,"
         "macro_collision,sub_collision\n";
}

void writeEventRows(std::ostream& out, const std::vector<ContactEvent>& events) {
  for (const ContactEvent& e : events) {
    out << exact(e.t_s) << "," << toString(e.pair.kind) << "," << e.pair.a << "," << e.pair.b << ","
        << toString(e.from) << "," << toString(e.to) << "," << (e.is_impact ? 1 : 0) << ","
        << exact(e.vn_before_mps) << "," << exact(e.vn_after_mps) << "," << exact(e.vt_before_mps)
        << "," << exact(e.vt_after_mps) << "," << exact(e.impulse_normal_Ns) << ","
        << exact(e.impulse_tangential_Ns) << "," << exact(e.energy_lost_J) << ","
        << exact(e.peak_normal_force_N) << "," << e.macro_collision << "," << e.sub_collision
        << "\n";
  }
}

// ---------------------------------------------------------------------------------------------
// Outcomes CSV.

void writeOutcomesCsv(std::ostream& out, const std::vector<KernelOutcome>& outcomes) {
  out << "kernel,peak_normal_force_N,time_of_peak_normal_s,peak_tangential_force_N,"
         "time_of_peak_tangential_s,peak_separation_s,max_contact_force_N,"
         "total_normal_impulse_Ns,impacts,"
         "macro_collisions,sub_collisions,sub_collisions_per_macro,max_sub_collisions,"
         "max_impact_energy_J,detached,detach_time_s,damage\n";
  const auto time = [](double t_s) { return t_s >= 0 ? exact(t_s) : std::string(); };
  for (size_t i = 0; i < outcomes.size(); ++i) {
    const KernelOutcome& o = outcomes[i];
    const bool both_peaks = o.time_of_peak_normal_s >= 0 && o.time_of_peak_tangential_s >= 0;
    out << i << "," << exact(o.peak_normal_force_N) << "," << time(o.time_of_peak_normal_s) << ","
        << exact(o.peak_tangential_force_N) << "," << time(o.time_of_peak_tangential_s) << ","
        << (both_peaks ? exact(o.peak_separation_s) : "") << "," << exact(o.max_contact_force_N)
        << "," << exact(o.total_normal_impulse_Ns) << "," << o.impacts << "," << o.macro_collisions
        << "," << o.sub_collisions << "," << exact(o.subCollisionsPerMacro()) << ","
        << o.max_sub_collisions << "," << exact(o.max_impact_energy_J) << ","
        << (o.detached ? 1 : 0) << "," << time(o.detach_time_s) << "," << toString(o.damage)
        << "\n";
  }
}

// ---------------------------------------------------------------------------------------------
// Contact force samples CSV.

void writeForcesHeader(std::ostream& out) {
  out << "t_s,kind,a,b,state,gap_m,normal_force_N,tangential_force_N\n";
}

void writeForceRows(std::ostream& out, const Data& data) {
  for (const ContactInfo& c : data.contacts) {
    out << exact(data.t_s) << "," << toString(c.pair.kind) << "," << c.pair.a << "," << c.pair.b
        << "," << toString(c.state) << "," << exact(c.gap_m) << "," << exact(c.normal_force_N)
        << "," << exact(c.tangential_force_N) << "\n";
  }
}

}  // namespace threshing_sim
