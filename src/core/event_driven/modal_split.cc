// The event-driven integrator's Lawson split of the modal teeth in contact
// (IntegratorParams::modal_split): a tooth's modal state y = [q; qdot] obeys
// y' = A y + [0; N], A the free tooth's state matrix at the drum speed (ToothPropagator) and N
// the contact forces' modal acceleration. In the interaction picture w(t) = exp(-A (t - t0)) y(t)
// the free part drops out, w' = exp(-A (t - t0)) [0; N], and the step applies the same
// Dormand-Prince tableau and error control to w: the modes are propagated exactly, only the
// contact force is integrated, so the step follows the contact, not the highest mode. Worked in
// modal amplitudes a = V^-1 y, where exp(A t) is diagonal (a_i' = lambda_i a_i + n_i).
// A plain Lawson step integrates exp(-lambda t) n, which turns at the mode's frequency even when
// the force is steady (a tooth pressed against a kernel): each fast mode is first shifted by its
// static amplitude under the step start's force, a*_i = -n_0i / lambda_i (constant over the step,
// so the shifted system b = a - a* is the same ODE with the forcing n - n_0: the order is kept,
// and a steady force is propagated exactly; a generalised integrating factor, Krogstad 2005).
// Stage s of the tooth is
//   a_s = a* + G(c_s) [a_0 - a* + h sum_j a_sj G(-c_j) (n_j - n_0)],   G(x) = exp(lambda x h),
// n_j = V^-1 [0; N_j] at stage j; its error estimate G(1) h sum_j e_j G(-c_j) (n_j - n_0). With
// N = 0 the step is the free propagator.
#include <cmath>
#include <complex>

#include "../modal_propagator.h"
#include "context.h"

namespace threshing_sim {
namespace internal {
namespace event_driven {

namespace {

// Largest decay -Re(lambda) h over a step for which exp(-lambda c h) is formed (beyond it the
// product G(c_s) G(-c_j) could overflow; such a tooth takes plain Dormand-Prince).
constexpr double kMaxDecay = 300.0;

// Smallest turn max_i |lambda_i| h [rad] of a tooth's fastest mode over a step for which it is
// split: a slower tooth's modes are smooth over the step, plain Dormand-Prince resolves them at
// no extra cost, and the transforms would only add theirs (the default strike's 4 modes over
// its contact steps: about 0.15 rad). Below the explicit method's stability bound (3.3) on the
// imaginary axis, so every step the modes would limit is split.
constexpr double kMinTurn = 1.0;

// Complex product and exponential written out in real arithmetic (the library's operators check
// for infinities and NaNs in a call per product; the values here are finite by kMaxDecay).
inline std::complex<double> mul(const std::complex<double>& a, const std::complex<double>& b) {
  return {a.real() * b.real() - a.imag() * b.imag(), a.real() * b.imag() + a.imag() * b.real()};
}
inline std::complex<double> expOf(const std::complex<double>& x) {
  const double r = std::exp(x.real());
  return {r * std::cos(x.imag()), r * std::sin(x.imag())};
}

// Growth and decay factors exp(+-lambda c_i h) of the nodes c_1..c_6 into the scratch; false if a
// mode decays too fast over h for them.
bool nodeFactors(const ToothPropagator& p, double h, ModalSplitScratch* sc) {
  const int n2 = static_cast<int>(p.lambda.size());
  for (int i = 0; i < n2; ++i)
    if (-p.lambda[i].real() * h > kMaxDecay) return false;
  // The nodes 1/5, 3/10, 4/5, 1 are multiples of 1/10: their factors are powers of
  // g = exp(lambda h / 10) (a few rounding errors each); 8/9 takes its own exponential.
  static_assert(kC[1] == 2. / 10 && kC[2] == 3. / 10 && kC[3] == 8. / 10 && kC[4] == 8. / 9 &&
                    kC[5] == 1.0 && kC[6] == 1.0,
                "nodeFactors assumes the Dormand-Prince nodes");
  for (int node = 0; node < 6; ++node) {
    sc->growth[node].resize(n2);
    sc->decay[node].resize(n2);
  }
  for (int i = 0; i < n2; ++i) {
    // One set per conjugate pair (as modalEvaluate).
    const bool conjugate_of_previous = i > 0 && p.lambda[i] == std::conj(p.lambda[i - 1]);
    for (int node = 0; node < 6; ++node) {
      std::complex<double>& g = sc->growth[node][i];
      if (conjugate_of_previous) {
        g = std::conj(sc->growth[node][i - 1]);
        continue;
      }
      switch (node) {
        case 0: {  // 2/10
          const std::complex<double> g1 = expOf(p.lambda[i] * (0.1 * h));
          g = mul(g1, g1);
          sc->growth[1][i] = mul(g, g1);  // 3/10
          break;
        }
        case 2:  // 8/10 = 3/10 + 3/10 + 2/10
          g = mul(mul(sc->growth[1][i], sc->growth[1][i]), sc->growth[0][i]);
          break;
        case 3:  // 8/9
          g = expOf(p.lambda[i] * (kC[4] * h));
          break;
        case 4:  // 1 = 8/10 + 2/10
          g = mul(sc->growth[2][i], sc->growth[0][i]);
          break;
        case 5:  // 1 (FSAL)
          g = sc->growth[4][i];
          break;
        default:  // 3/10, set with 2/10
          break;
      }
    }
    for (int node = 0; node < 6; ++node) {
      // 1 / g = conj(g) / |g|^2 (finite and nonzero by kMaxDecay).
      const std::complex<double>& g = sc->growth[node][i];
      sc->decay[node][i] = std::conj(g) / std::norm(g);
    }
  }
  return true;
}

// The real and imaginary parts of V and of V^-1's velocity columns, for real matrix-vector
// products (vectorised; the complex loops cost several times more at 20 modes). Rebuilt when the
// propagator is (another drum speed).
void realFactors(const ToothPropagator& p, int n, ModalSplitScratch* sc) {
  if (sc->factors_omega_radps == p.omega_radps && sc->V_re.rows() == 2 * n) return;
  sc->factors_omega_radps = p.omega_radps;
  sc->V_re = p.V.real();
  sc->V_im = p.V.imag();
  sc->Vinv_u_re = p.V_inv.rightCols(n).real();
  sc->Vinv_u_im = p.V_inv.rightCols(n).imag();
  sc->a_re.resize(2 * n);
  sc->a_im.resize(2 * n);
  sc->N.resize(n);
  sc->nk_re.resize(2 * n);
  sc->nk_im.resize(2 * n);
}

// y = Re(V a) = V_re Re(a) - V_im Im(a) into (q, qd).
void evaluateAmplitudes(ModalSplitScratch* sc, int n, const Eigen::VectorXcd& a, Eigen::Ref<VecX> q,
                        Eigen::Ref<VecX> qd) {
  for (int i = 0; i < 2 * n; ++i) {
    sc->a_re[i] = a[i].real();
    sc->a_im[i] = a[i].imag();
  }
  q.noalias() = sc->V_re.topRows(n) * sc->a_re;
  q.noalias() -= sc->V_im.topRows(n) * sc->a_im;
  qd.noalias() = sc->V_re.bottomRows(n) * sc->a_re;
  qd.noalias() -= sc->V_im.bottomRows(n) * sc->a_im;
}

// The static shift of each mode, a*_i = -n_0i / lambda_i (the amplitude at which the step
// start's contact term n_0 holds the mode still), for the modes that turn by at least
// kShiftTurn radians (or decay by as much) over h; 0 for slower modes, whose interaction picture
// is smooth over the step anyway.
constexpr double kShiftTurn = 0.1;
void staticShift(const ToothPropagator& p, double h, ModalSplitScratch* sc) {
  for (int i = 0; i < sc->shift.size(); ++i) {
    const std::complex<double> l = p.lambda[i];
    const double l2 = std::norm(l);
    sc->shift[i] = l2 * h * h >= kShiftTurn * kShiftTurn ? -mul(sc->n_k[0][i], std::conj(l)) / l2
                                                         : std::complex<double>(0.0, 0.0);
  }
}

// The contact term of stage j less the step start's on the modes that carry a static shift [mixed
// / s]: n_j - n_0 there, n_j elsewhere.
inline std::complex<double> shiftedTerm(const ModalSplitScratch& sc, int j, int i) {
  return sc.shift[i] == 0.0 ? sc.n_k[j][i] : sc.n_k[j][i] - sc.n_k[0][i];
}

// w = (a_0 - a*) + h sum_{j < s} a_sj G(-c_j) (n_j - n_0) (weights row of the tableau, s stages),
// into sc->a.
void interactionSum(ModalSplitScratch* sc, int n2, const double* weights, int s, double h) {
  Eigen::VectorXcd& w = sc->a;
  for (int i = 0; i < n2; ++i) w[i] = sc->a0[i] - sc->shift[i];
  for (int j = 0; j < s; ++j) {
    if (weights[j] == 0.0) continue;
    const double b = h * weights[j];
    for (int i = 0; i < n2; ++i)
      w[i] +=
          b * (j == 0 ? shiftedTerm(*sc, 0, i) : mul(sc->decay[j - 1][i], shiftedTerm(*sc, j, i)));
  }
}

}  // namespace

int beginModalSplit(const Ctx& c, double h, const VecX& z0, const VecX& u0) {
  const Model& m = c.m;
  Workspace& ws = c.ws;
  const int T = static_cast<int>(m.teeth.size());
  ws.ed.tooth_split.assign(T, 0);
  if (!m.integrator.modal_split || c.d.omega_radps != c.d.omega_target_radps) return 0;
  if (ws.ed.prop.size() != static_cast<size_t>(T)) ws.ed.prop.resize(T);
  if (ws.ed.split.size() != static_cast<size_t>(T)) ws.ed.split.resize(T);
  growTo(&ws.ed.err_split, 2 * m.n_dof);
  int marked = 0;
  for (int k = 0; k < T; ++k) {
    const ToothModel& tm = m.teeth[k];
    if (tm.n_modes == 0 || (k < static_cast<int>(ws.ed.tooth_exact.size()) && ws.ed.tooth_exact[k]))
      continue;
    if (!buildToothPropagator(m, k, c.d.omega_radps, &ws.ed.prop[k])) continue;
    if (ws.ed.prop[k].lambda.cwiseAbs().maxCoeff() * h < kMinTurn) continue;
    ModalSplitScratch& sc = ws.ed.split[k];
    if (!nodeFactors(ws.ed.prop[k], h, &sc)) continue;
    const int n2 = 2 * tm.n_modes;
    sc.a0.resize(n2);
    sc.a.resize(n2);
    sc.shift.setZero(n2);
    for (Eigen::VectorXcd& v : sc.n_k) v.resize(n2);
    realFactors(ws.ed.prop[k], tm.n_modes, &sc);
    modalAmplitudes(ws.ed.prop[k].V_inv, tm.n_modes, z0.segment(tm.dof_offset, tm.n_modes),
                    u0.segment(tm.dof_offset, tm.n_modes), sc.a0);
    ws.ed.tooth_split[k] = 1;
    ++marked;
  }
  return marked;
}

void modalSplitStageState(const Ctx& c, int s, double h) {
  Workspace& ws = c.ws;
  for (size_t k = 0; k < ws.ed.tooth_split.size(); ++k) {
    if (!ws.ed.tooth_split[k]) continue;
    const ToothModel& tm = c.m.teeth[k];
    const int n = tm.n_modes;
    ModalSplitScratch& sc = ws.ed.split[k];
    if (s == 1) staticShift(ws.ed.prop[k], h, &sc);  // from the first stage's contact term
    interactionSum(&sc, 2 * n, kA[s], s, h);
    if (s > 0)
      for (int i = 0; i < 2 * n; ++i) sc.a[i] = mul(sc.a[i], sc.growth[s - 1][i]) + sc.shift[i];
    evaluateAmplitudes(&sc, n, sc.a, ws.ed.zz.segment(tm.dof_offset, n),
                       ws.ed.uu.segment(tm.dof_offset, n));
  }
}

void modalSplitStoreStage(const Ctx& c, int s, double omega_radps) {
  Workspace& ws = c.ws;
  const double w2 = omega_radps * omega_radps;
  for (size_t k = 0; k < ws.ed.tooth_split.size(); ++k) {
    if (!ws.ed.tooth_split[k]) continue;
    const ToothModel& tm = c.m.teeth[k];
    const int n = tm.n_modes;
    const int o = tm.dof_offset;
    ModalSplitScratch& sc = ws.ed.split[k];
    const auto q = ws.ed.zz.segment(o, n);
    const auto qd = ws.ed.uu.segment(o, n);
    // N: the stage's acceleration minus the free tooth's (smoothForces' terms at constant drum
    // speed), the contact forces' modal acceleration; first K_G q into N.
    sc.N.noalias() = tm.K_G * q;
    for (int i = 0; i < n; ++i) {
      const double free_i =
          -w2 * sc.N[i] + (-(tm.omega0_sq[i] - w2) * q[i] - tm.damping_coeff[i] * qd[i]);
      sc.N[i] = ws.ed.udot[o + i] - free_i;
    }
    // n_s = V^-1 [0; N] by the real and imaginary parts of V^-1's velocity columns.
    sc.nk_re.noalias() = sc.Vinv_u_re * sc.N;
    sc.nk_im.noalias() = sc.Vinv_u_im * sc.N;
    Eigen::VectorXcd& nk = sc.n_k[s];
    for (int r = 0; r < 2 * n; ++r) nk[r] = std::complex<double>(sc.nk_re[r], sc.nk_im[r]);
  }
}

void modalSplitError(const Ctx& c, double h) {
  Workspace& ws = c.ws;
  const int nd = c.m.n_dof;
  for (size_t k = 0; k < ws.ed.tooth_split.size(); ++k) {
    if (!ws.ed.tooth_split[k]) continue;
    const ToothModel& tm = c.m.teeth[k];
    const int n = tm.n_modes;
    ModalSplitScratch& sc = ws.ed.split[k];
    // h sum_j e_j G(-c_j) (n_j - n_0) (without a_0), carried to the step end by G(1).
    sc.a.setZero();
    for (int j = 0; j < 7; ++j) {
      if (kE[j] == 0.0) continue;
      const double b = h * kE[j];
      for (int i = 0; i < 2 * n; ++i)
        sc.a[i] +=
            b * (j == 0 ? shiftedTerm(sc, 0, i) : mul(sc.decay[j - 1][i], shiftedTerm(sc, j, i)));
    }
    for (int i = 0; i < 2 * n; ++i) sc.a[i] = mul(sc.a[i], sc.growth[5][i]);
    evaluateAmplitudes(&sc, n, sc.a, ws.ed.err_split.segment(tm.dof_offset, n),
                       ws.ed.err_split.segment(nd + tm.dof_offset, n));
    std::fill_n(ws.ed.own_error.begin() + tm.dof_offset, n, 2);
  }
}

}  // namespace event_driven
}  // namespace internal
}  // namespace threshing_sim
