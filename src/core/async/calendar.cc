// Asynchronous core, stage "calendar": when a lazy kernel must next be looked at.
//   - every lazy kernel holds a bound circle (centre, radius) that contains it until its wake
//     time: its pose at its own clock, grown by a bound on its speed times the horizon;
//   - the wake times form a binary min-heap (ties broken by kernel index: deterministic);
//   - the circles' centres sit in a uniform grid (open addressing, lists through the kernels),
//     so that a query costs the cells it covers, not the kernel count;
//   - predictKernel chooses the horizon: no longer than a cap on the circle's growth, and short
//     enough that the kernel's ellipse, grown by its bound, stays a broad-phase margin away from
//     every other lazy kernel's grown ellipse and every obstacle. Where even the current window
//     does not fit, the two must share an island: a join.
#include "async.h"

namespace threshing_sim {
namespace internal {
namespace {

bool earlier(const AsyncState& as, int i, int j) {
  const double wi = as.kernels[i].wake_s, wj = as.kernels[j].wake_s;
  return wi < wj || (wi == wj && i < j);
}

void heapSwap(AsyncState* as, int a, int b) {
  std::swap(as->heap[a], as->heap[b]);
  as->kernels[as->heap[a]].heap_pos = a;
  as->kernels[as->heap[b]].heap_pos = b;
}

void siftUp(AsyncState* as, int pos) {
  while (pos > 0) {
    const int parent = (pos - 1) / 2;
    if (!earlier(*as, as->heap[pos], as->heap[parent])) break;
    heapSwap(as, pos, parent);
    pos = parent;
  }
}

void siftDown(AsyncState* as, int pos) {
  const int n = static_cast<int>(as->heap.size());
  while (true) {
    const int l = 2 * pos + 1, r = l + 1;
    int best = pos;
    if (l < n && earlier(*as, as->heap[l], as->heap[best])) best = l;
    if (r < n && earlier(*as, as->heap[r], as->heap[best])) best = r;
    if (best == pos) break;
    heapSwap(as, pos, best);
    pos = best;
  }
}

std::int64_t cellKey(std::int64_t cx, std::int64_t cy) { return gridCellKey(cx, cy); }

std::int64_t cellOf(const AsyncState& as, const Vec2& p) {
  return cellKey(cellFloor(p.x() / as.cell_m), cellFloor(p.y() / as.cell_m));
}

// Bits 40 and up of the product: the row sits in the key's high 32 bits, which reach only the
// product's high half (bits below 32 would give every cell of a column one slot: long probe
// runs through a field of kernels). Tables of up to 2^24 slots.
size_t slotHash(std::int64_t key, size_t n_slots) {
  const std::uint64_t h = static_cast<std::uint64_t>(key) * 0x9E3779B97F4A7C15ULL;
  return static_cast<size_t>(h >> 40) & (n_slots - 1);
}

// Table slot of a cell key: its slot, or the empty slot where it would go.
size_t findSlot(const AsyncState& as, std::int64_t key) {
  const size_t n = as.cell_key.size();
  size_t s = slotHash(key, n);
  while (as.cell_key[s] != key && as.cell_key[s] != kEmptyCell) s = (s + 1) & (n - 1);
  return s;
}

// Table slot of kernel i's cell (kc.cell set from its circle's centre), the key added if new.
size_t cellSlot(AsyncState* as, KernelClock* kc) {
  kc->cell = cellOf(*as, kc->bound_c_W);
  const size_t s = findSlot(*as, kc->cell);
  if (as->cell_key[s] == kEmptyCell) {
    as->cell_key[s] = kc->cell;
    as->cell_head[s] = -1;
    ++as->cells_used;
  }
  return s;
}

// Lists kernel i in the cell of its bound circle's centre (the table has room).
void listInCell(AsyncState* as, int i) {
  KernelClock& kc = as->kernels[i];
  const size_t s = cellSlot(as, &kc);
  kc.cell_prev = -1;
  kc.cell_next = as->cell_head[s];
  if (kc.cell_next >= 0) as->kernels[kc.cell_next].cell_prev = i;
  as->cell_head[s] = i;
  kc.in_grid = true;
  kc.listing = GridListing::kSince;
  as->r_listed_m = std::max(as->r_listed_m, kc.bound_r_m);
}

// Writes the sleeping field into the grid: each of its kernels where set-up would have listed
// it, in its cell's set-up part by descending index (after the kernels listed since set-up).
void listField(AsyncState* as) {
  KernelClock* kcs = as->kernels.data();
  const int K = static_cast<int>(as->kernels.size());
  for (int i = 0; i < K && as->field_unlisted > 0; ++i) {
    KernelClock& kc = kcs[i];
    if (kc.listing != GridListing::kUnlisted) continue;
    kc.t_s = as->field_t_s;  // the field's clock
    const size_t s = cellSlot(as, &kc);
    int prev = -1, next = as->cell_head[s];
    while (next >= 0 && (kcs[next].listing != GridListing::kAtSetUp || next > i)) {
      prev = next;
      next = kcs[next].cell_next;
    }
    kc.cell_prev = prev;
    kc.cell_next = next;
    (prev >= 0 ? kcs[prev].cell_next : as->cell_head[s]) = i;
    if (next >= 0) kcs[next].cell_prev = i;
    kc.listing = GridListing::kAtSetUp;
    --as->field_unlisted;
  }
}

// Distances from the drum axis of the points of cells k0..k1 along one axis [m]: the nearest
// and the farthest, each by slack_m beyond (a centre listed in a cell lies in it up to the
// rounding of its division, far below the slack).
void cellSpan(std::int64_t k0, std::int64_t k1, double cell_m, double slack_m, double* near_m,
              double* far_m) {
  const double a = static_cast<double>(k0) * cell_m - slack_m;
  const double b = static_cast<double>(k1 + 1) * cell_m + slack_m;
  *near_m = a > 0.0 ? a : (b < 0.0 ? -b : 0.0);
  *far_m = std::max(std::abs(a), std::abs(b));
}

// Whether a centre of the sleeping field may lie in the cells [x0, x1] x [y0, y1]: their
// distances from the drum axis meet the field's ring of centres (no field: false).
bool meetsField(const AsyncState& as, std::int64_t x0, std::int64_t x1, std::int64_t y0,
                std::int64_t y1) {
  if (as.field_unlisted == 0) return false;
  const double slack = 1e-6 * as.cell_m;
  double nx = 0.0, fx = 0.0, ny = 0.0, fy = 0.0;
  cellSpan(x0, x1, as.cell_m, slack, &nx, &fx);
  cellSpan(y0, y1, as.cell_m, slack, &ny, &fy);
  return !(std::sqrt(nx * nx + ny * ny) > as.field_rho_hi_m) &&
         !(std::sqrt(fx * fx + fy * fy) < as.field_rho_lo_m);
}

// Sets p[0..n) to v, eight stores a round (which the compiler writes as vector stores: a table
// of thousands of slots is emptied at every set-up), then the rest one by one.
template <typename T>
void fillByEights(T* p, size_t n, T v) {
  size_t b = 0;
  for (; b + 8 <= n; b += 8)
    for (size_t j = 0; j < 8; ++j) p[b + j] = v;
  for (; b < n; ++b) p[b] = v;
}

// Empties the table, at `slots` slots (a power of two).
void clearTable(AsyncState* as, size_t slots) {
  as->cell_key.resize(slots);
  as->cell_head.resize(slots);
  fillByEights(as->cell_key.data(), slots, kEmptyCell);
  fillByEights(as->cell_head.data(), slots, -1);
}

// Set-up's listing of the kernels not asleep, in index order, each at the head of its cell's
// list (the set-up part). Kernels in a run in one cell share its table lookup.
void listAwakeAtSetUp(AsyncState* as) {
  KernelClock* clocks = as->kernels.data();
  const int K = static_cast<int>(as->kernels.size());
  std::int64_t* cell_key = as->cell_key.data();
  int* cell_head = as->cell_head.data();
  const size_t slots = as->cell_key.size();
  const double cell_m = as->cell_m;
  std::int64_t memo_key = kEmptyCell;  // the last cell and its slot
  size_t memo_slot = 0;
  size_t cells_used = 0;
  for (int i = 0; i < K; ++i) {
    KernelClock& kc = clocks[i];
    if (kc.listing != GridListing::kAtSetUp) continue;
    kc.cell = cellKey(cellFloor(kc.bound_c_W.x() / cell_m), cellFloor(kc.bound_c_W.y() / cell_m));
    if (kc.cell != memo_key) {
      memo_key = kc.cell;
      memo_slot = slotHash(kc.cell, slots);
      while (cell_key[memo_slot] != kc.cell && cell_key[memo_slot] != kEmptyCell)
        memo_slot = (memo_slot + 1) & (slots - 1);  // (findSlot, the table's size known)
      if (cell_key[memo_slot] == kEmptyCell) {
        cell_key[memo_slot] = kc.cell;
        ++cells_used;
      }
    }
    kc.cell_next = cell_head[memo_slot];
    if (kc.cell_next >= 0) clocks[kc.cell_next].cell_prev = i;
    cell_head[memo_slot] = i;
  }
  as->cells_used += cells_used;
}

// Rebuilds the table from the listed kernels once half its slots hold keys (cells that emptied
// keep their keys until then); it doubles while the listed kernels alone would fill half. The
// sleeping field is listed with the others.
void compactGrid(AsyncState* as) {
  size_t listed = 0;
  for (const KernelClock& kc : as->kernels) listed += kc.in_grid ? 1 : 0;
  size_t slots = std::max<size_t>(as->cell_key.size(), 16);
  while (4 * (listed + 1) > slots) slots *= 2;
  clearTable(as, slots);
  as->cells_used = 0;
  for (size_t i = 0; i < as->kernels.size(); ++i) {
    KernelClock& kc = as->kernels[i];
    if (kc.listing == GridListing::kUnlisted) kc.t_s = as->field_t_s;  // the field's clock
    if (kc.in_grid) listInCell(as, static_cast<int>(i));
  }
  as->field_unlisted = 0;
}

}  // namespace

double ellipseGapBound(const OrientedEllipse& e1, const OrientedEllipse& e2) {
  const Vec2 d_W = e2.center_W - e1.center_W;
  const double dist_m = d_W.norm();
  if (!(dist_m > 0.0)) return -e1.a_m - e2.a_m;
  const Vec2 n_W = d_W / dist_m;
  // Support of an ellipse along n: sqrt(a^2 (n.u)^2 + b^2 (n x u)^2), u its unit a-axis.
  auto support = [&n_W](const OrientedEllipse& e) {
    const Vec2& u = e.axis_W;
    const double na_m = e.a_m * n_W.dot(u), nb_m = e.b_m * (u.x() * n_W.y() - u.y() * n_W.x());
    return std::sqrt(na_m * na_m + nb_m * nb_m);
  };
  return dist_m - support(e1) - support(e2);
}

bool pairMayTouch(const OrientedEllipse& e1, const OrientedEllipse& e2, double reach_m) {
  const double circles_m = e1.a_m + e2.a_m + reach_m;
  if ((e2.center_W - e1.center_W).squaredNorm() > circles_m * circles_m) return false;
  return ellipseGapBound(e1, e2) <= reach_m;
}

OrientedEllipse orientedKernel(const Model& m, const VecX& z, const AsyncState& as, int i) {
  const KernelModel& k = m.kernels[i];
  const KernelClock& kc = as.kernels[i];
  const double psi_rad = z[k.dof_offset + 2];
  if (!(kc.axis_psi_rad == psi_rad)) {
    kc.axis_W = Vec2(std::cos(psi_rad), std::sin(psi_rad));
    kc.axis_psi_rad = psi_rad;
  }
  OrientedEllipse e;
  e.center_W = z.segment<2>(k.dof_offset);
  e.axis_W = kc.axis_W;
  e.a_m = k.semi_axis_a_m;
  e.b_m = k.semi_axis_b_m;
  return e;
}

void heapPush(AsyncState* as, int i) {
  as->kernels[i].heap_pos = static_cast<int>(as->heap.size());
  as->heap.push_back(i);
  siftUp(as, as->kernels[i].heap_pos);
}

void heapRemove(AsyncState* as, int i) {
  as->kernels[i].rest_until_s = -std::numeric_limits<double>::infinity();
  const int pos = as->kernels[i].heap_pos;
  if (pos < 0) return;
  const int last = static_cast<int>(as->heap.size()) - 1;
  if (pos != last) heapSwap(as, pos, last);
  as->heap.pop_back();
  as->kernels[i].heap_pos = -1;
  if (pos < static_cast<int>(as->heap.size())) {
    siftDown(as, pos);
    siftUp(as, pos);
  }
}

int heapTop(const AsyncState& as) { return as.heap.empty() ? -1 : as.heap[0]; }

void gridInsert(AsyncState* as, int i) {
  KernelClock& kc = as->kernels[i];
  if (kc.in_grid) return;
  // The keys include the field's cells (listing it at set-up would have added them): where
  // those might bring the keys to half the table, the field is written first, its cells counted.
  if (as->field_unlisted > 0 &&
      2 * (as->cells_used + static_cast<size_t>(as->field_unlisted) + 1) > as->cell_key.size())
    listField(as);
  if (2 * (as->cells_used + 1) > as->cell_key.size()) compactGrid(as);
  listInCell(as, i);
}

int listKernelsAtSetUp(const Model& m, const Data& d, AsyncState* as) {
  const int K = static_cast<int>(m.kernels.size());
  const double t_s = d.t_s, horizon = as->max_horizon_s, tol = m.integrator.tolerance;
  const double rest_speed = tol * 1e-2 / horizon, grow_m = rest_speed * horizon;
  // Every clock starts as a sleeping field kernel's (the common case): a kernel asleep gets its
  // circle and calendar position, any other a fresh clock.
  KernelClock asleep_clock;
  asleep_clock.t_s = t_s;
  asleep_clock.rest_until_s = t_s + horizon;
  asleep_clock.wake_s = t_s + horizon;
  asleep_clock.speed_bound_mps = rest_speed;
  asleep_clock.motion = KernelMotion::kPedicel;
  asleep_clock.in_grid = true;
  asleep_clock.listing = GridListing::kUnlisted;
  as->kernels.assign(K, asleep_clock);
  KernelClock* clocks = as->kernels.data();
  as->heap.resize(K);  // (the asleep, in index order: a heap of equal wake times)
  int* heap = as->heap.data();
  int asleep = 0;
  const Vec2 g = m.gravity_mps2;
  const KernelModel* kms = m.kernels.data();
  const double* z = d.z.data();
  const double* u = d.u.data();
  const std::uint8_t* attached = d.kernel_attached.data();
  double psi_rad = 0.0, cos_psi = 1.0, sin_psi = 0.0;  // the last angle's cosine and sine
  double a_max = 0.0;                                  // the largest semi-axis a [m]
  // The sleeping field's ring: the least and largest |c|^2 of its centres.
  double rr_lo = std::numeric_limits<double>::infinity(), rr_hi = 0.0;
  for (int i = 0; i < K; ++i) {
    KernelClock& kc = clocks[i];
    const KernelModel& k = kms[i];
    const double* zi = z + k.dof_offset;
    const double x = zi[0], y = zi[1];
    a_max = std::max(a_max, k.semi_axis_a_m);
    kc.bound_c_W = Vec2(x, y);
    if (k.pedicel.present && attached[i]) {
      if (!(zi[2] == psi_rad)) {
        psi_rad = zi[2];
        cos_psi = std::cos(psi_rad);
        sin_psi = std::sin(psi_rad);
      }
      if (restsOnPedicel(k, g, tol, zi, u + k.dof_offset, cos_psi, sin_psi, horizon)) {
        // Asleep, in the sleeping field: its cell is written when something comes near.
        kc.bound_r_m = k.semi_axis_a_m + grow_m;
        kc.heap_pos = asleep;
        heap[asleep++] = i;
        const double rr = x * x + y * y;
        rr_lo = std::min(rr_lo, rr);
        rr_hi = std::max(rr_hi, rr);
        continue;
      }
    }
    // Not asleep: listed with its ungrown circle below (and predicted by the caller).
    kc = KernelClock();
    kc.t_s = t_s;
    kc.bound_c_W = Vec2(x, y);
    kc.bound_r_m = k.semi_axis_a_m;
    kc.motion = k.pedicel.present && attached[i] ? KernelMotion::kPedicel : KernelMotion::kFree;
    kc.in_grid = true;
    kc.listing = GridListing::kAtSetUp;
  }
  as->heap.resize(asleep);
  as->field_unlisted = asleep;
  as->field_t_s = t_s;
  as->field_rho_lo_m = std::sqrt(rr_lo);
  as->field_rho_hi_m = std::sqrt(rr_hi);
  as->counters.asleep += asleep;
  // The grid: cells twice the largest bound radius; every circle listed here is a semi-axis a
  // grown by at most the error scale.
  as->r_cap_m = std::max(a_max, 1e-6) + 4.0 * m.broadphase_margin_m;
  as->cell_m = 2.0 * as->r_cap_m;
  as->r_listed_m = a_max + grow_m;
  size_t slots = 64;
  while (slots < 4 * static_cast<size_t>(K) + 64) slots *= 2;  // K keys at most: no rebuild
  clearTable(as, slots);
  as->cells_used = 0;
  if (asleep < K) listAwakeAtSetUp(as);
  return K - asleep;
}

void gridRemove(AsyncState* as, int i) {
  KernelClock& kc = as->kernels[i];
  if (!kc.in_grid) return;
  if (kc.listing == GridListing::kUnlisted) listField(as);
  kc.listing = GridListing::kSince;
  if (kc.cell_prev >= 0) {
    as->kernels[kc.cell_prev].cell_next = kc.cell_next;
  } else {
    as->cell_head[findSlot(*as, kc.cell)] = kc.cell_next;
  }
  if (kc.cell_next >= 0) as->kernels[kc.cell_next].cell_prev = kc.cell_prev;
  kc.cell_next = kc.cell_prev = -1;
  kc.in_grid = false;
}

void gridQuery(AsyncState* as, const Vec2& lo, const Vec2& hi) {
  as->found.clear();
  const double pad = as->r_cap_m;
  const std::int64_t x0 = cellFloor((lo.x() - pad) / as->cell_m);
  const std::int64_t x1 = cellFloor((hi.x() + pad) / as->cell_m);
  const std::int64_t y0 = cellFloor((lo.y() - pad) / as->cell_m);
  const std::int64_t y1 = cellFloor((hi.y() + pad) / as->cell_m);
  if ((x1 - x0 + 1) * (y1 - y0 + 1) > static_cast<std::int64_t>(as->cell_key.size())) {
    // A box larger than the table: every listed kernel is a candidate.
    for (size_t i = 0; i < as->kernels.size(); ++i)
      if (as->kernels[i].in_grid) as->found.push_back(static_cast<int>(i));
    return;
  }
  if (meetsField(*as, x0, x1, y0, y1)) listField(as);
  for (std::int64_t cy = y0; cy <= y1; ++cy) {
    for (std::int64_t cx = x0; cx <= x1; ++cx) {
      const size_t s = findSlot(*as, cellKey(cx, cy));
      if (as->cell_key[s] == kEmptyCell) continue;
      for (int j = as->cell_head[s]; j >= 0; j = as->kernels[j].cell_next) as->found.push_back(j);
    }
  }
}

void gridQueryAnnulus(AsyncState* as, const Vec2& lo, const Vec2& hi, double r_lo_m,
                      double r_hi_m) {
  as->found.clear();
  const double pad = as->r_cap_m, c = as->cell_m;
  const std::int64_t x0 = cellFloor((lo.x() - pad) / c), x1 = cellFloor((hi.x() + pad) / c);
  const std::int64_t y0 = cellFloor((lo.y() - pad) / c), y1 = cellFloor((hi.y() + pad) / c);
  if ((x1 - x0 + 1) * (y1 - y0 + 1) > static_cast<std::int64_t>(as->cell_key.size())) {
    gridQuery(as, lo, hi);  // every listed kernel
    as->swept_kernels += static_cast<long>(as->found.size());
    return;
  }
  // A centre listed in cell (cx, cy) lies in [cx c, (cx + 1) c] x [cy c, (cy + 1) c] up to the
  // rounding of its division, far below the slack; its circle's radius is at most r_listed_m.
  // The cell's box, grown by the slack, bounds |p| of its centres from below (near) and above
  // (far): a circle there with rho - r > r_hi or rho + r < r_lo is clear of the annulus.
  const double slack = 1e-6 * c;
  const double reach = as->r_listed_m + slack;
  // The sleeping field, where the box meets its cells: passed over whole when its ring of
  // centres, grown by the listed radii, misses the annulus (each circle would), else listed.
  if (as->field_unlisted > 0 && !(as->field_rho_lo_m - reach > r_hi_m) &&
      !(as->field_rho_hi_m + reach < r_lo_m) && meetsField(*as, x0, x1, y0, y1))
    listField(as);
  auto nearFar = [c, slack](std::int64_t k, double* near, double* far) {
    cellSpan(k, k, c, slack, near, far);
  };
  for (std::int64_t cy = y0; cy <= y1; ++cy) {
    double ny = 0.0, fy = 0.0;
    nearFar(cy, &ny, &fy);
    for (std::int64_t cx = x0; cx <= x1; ++cx) {
      const size_t s = findSlot(*as, cellKey(cx, cy));
      if (as->cell_key[s] == kEmptyCell || as->cell_head[s] < 0) continue;
      double nx = 0.0, fx = 0.0;
      nearFar(cx, &nx, &fx);
      if (std::sqrt(nx * nx + ny * ny) - reach > r_hi_m ||
          std::sqrt(fx * fx + fy * fy) + reach < r_lo_m)
        continue;  // the whole cell is out of reach
      for (int j = as->cell_head[s]; j >= 0; j = as->kernels[j].cell_next) {
        as->found.push_back(j);
        ++as->swept_kernels;
      }
    }
  }
}

namespace {
// Longest horizon (up to max_s) over which lazy kernel i's growth V(H) H stays within
// grow_cap_m, and the speed bound V over it (bisection on the monotone growth).
double horizonFor(const Model& m, const Data& d, const AsyncState& as, int i, double grow_cap_m,
                  double max_s, double* v_mps) {
  double lo = 0.0, hi = max_s;
  const LazySpeedTerms terms = lazySpeedTerms(m, d, as, i);  // once: the bisection needs only H
  if (lazySpeedBoundAt(terms, hi) * hi > grow_cap_m) {
    for (int it = 0; it < 40; ++it) {
      const double mid = 0.5 * (lo + hi);
      (lazySpeedBoundAt(terms, mid) * mid > grow_cap_m ? hi : lo) = mid;
    }
    hi = lo;
  }
  *v_mps = std::max(lazySpeedBoundAt(terms, hi), 1e-12);
  return hi;
}
}  // namespace

namespace {
// Shortens *horizon_s so that kernel i's ellipse e, grown by v_mps times the horizon, leaves
// every other lazy kernel its share of the gap and every obstacle a margin. A neighbour or
// obstacle that does not leave room even for min_horizon_s is a join when add_joins (else
// nothing is added). Returns whether every one left that room.
bool fitHorizon(const Model& m, const Data& d, AsyncState* as, int i, const OrientedEllipse& e,
                double v_mps, double min_horizon_s, bool add_joins, double* horizon_s) {
  const KernelModel& k = m.kernels[i];
  const int T = static_cast<int>(m.teeth.size());
  const double margin = m.broadphase_margin_m;
  bool fits = true;
  // Other lazy kernels: the grown ellipses must stay a margin apart.
  const double reach = k.semi_axis_a_m + v_mps * *horizon_s + margin;
  gridQuery(as, e.center_W - Vec2(reach, reach), e.center_W + Vec2(reach, reach));
  for (int j : as->found) {
    if (j == i) continue;
    const KernelClock& kj = as->kernels[j];
    if ((kj.bound_c_W - e.center_W).norm() > kj.bound_r_m + reach) continue;
    // Each of two neighbours may grow into at most half of the free gap between them, so that
    // the one predicted later still finds its share.
    const double free_m = ellipseGapBound(e, orientedKernel(m, d.z, *as, j)) - margin;
    const double grown_j = kj.bound_r_m - m.kernels[j].semi_axis_a_m;
    const double room = std::min(free_m - grown_j, 0.5 * free_m);
    if (room >= v_mps * min_horizon_s) {
      *horizon_s = std::min(*horizon_s, room / v_mps);
    } else {
      if (add_joins) as->joins.emplace_back(T + i, T + j);
      fits = false;
    }
  }
  // Obstacles: the grown bounding circle must stay a margin away.
  for (const ObstacleModel& o : m.obstacles) {
    const double room = obstacleClearance(o, e.center_W) - k.semi_axis_a_m - margin;
    if (room >= v_mps * min_horizon_s) {
      *horizon_s = std::min(*horizon_s, room / v_mps);
    } else {
      if (add_joins) as->joins.emplace_back(T + i, T + i);
      fits = false;
    }
  }
  return fits;
}

// A kernel on its pedicel whose closed form holds over the longest horizon stays inside its
// ellipse grown by the oscillation's envelope (pedicelEnvelope), however long: if that growth
// fits within the cap, its neighbours' shares and the obstacles' margins, it keeps the longest
// horizon (its speed is then the growth over that horizon). Returns whether it does.
bool envelopeFits(const Model& m, const Data& d, AsyncState* as, int i, const OrientedEllipse& e,
                  double cap_m, double* v_mps) {
  double growth_m = 0.0;
  const double horizon = as->max_horizon_s;
  if (!pedicelEnvelope(m, d, as, i, horizon, &growth_m) || !(growth_m <= cap_m)) return false;
  const double v = std::max(growth_m / horizon, 1e-300);
  double h = horizon;
  if (!fitHorizon(m, d, as, i, e, v, horizon, false, &h)) return false;
  *v_mps = v;
  return true;
}
}  // namespace

bool predictKernel(const Model& m, const Data& d, AsyncState* as, int i, double t_s,
                   double t_window_end_s, double grow_cap_m) {
  KernelClock& kc = as->kernels[i];
  const KernelModel& k = m.kernels[i];
  const int T = static_cast<int>(m.teeth.size());
  ++as->counters.predictions;
  // Horizon: the circle may grow by at most the cap (and never past the grid's radius).
  const double cap = std::min(grow_cap_m, as->r_cap_m - k.semi_axis_a_m);
  const OrientedEllipse e = orientedKernel(m, d.z, *as, i);
  // A kernel at rest on its pedicel over the longest horizon moves by less than the error scale
  // until something reaches it: it sleeps, with a circle grown by that scale only. One swinging
  // within its closed form's validity keeps the envelope of its oscillation.
  double v = 0.0, horizon = as->max_horizon_s;
  const bool pedicel = kc.motion == KernelMotion::kPedicel;
  kc.rest_until_s = -std::numeric_limits<double>::infinity();
  if (pedicel && lazyAtRest(m, d, i, horizon)) {
    v = m.integrator.tolerance * 1e-2 / horizon;
    ++as->counters.asleep;
    kc.rest_until_s = kc.t_s + horizon;
  } else if (!(pedicel && envelopeFits(m, d, as, i, e, cap, &v))) {
    horizon = horizonFor(m, d, *as, i, cap, as->max_horizon_s, &v);
  }
  const double min_horizon = t_window_end_s - t_s;
  bool joined = !fitHorizon(m, d, as, i, e, v, min_horizon, true, &horizon);
  kc.bound_c_W = e.center_W;
  kc.bound_r_m = k.semi_axis_a_m + v * horizon;
  kc.wake_s = t_s + horizon;
  kc.speed_bound_mps = v;
  if (!joined && kc.wake_s < t_window_end_s) {
    // Too fast to stay lazy over the window: it is integrated, alone if nothing is near.
    as->joins.emplace_back(T + i, T + i);
    joined = true;
  }
  if (joined) return false;  // it goes into an island this window
  gridInsert(as, i);
  heapPush(as, i);
  return true;
}

double obstacleClearance(const ObstacleModel& o, const Vec2& c) {
  if (o.type == ObstacleType::kPlane) return o.normal.dot(c - o.point_m);
  if (o.type == ObstacleType::kCircle) return (c - o.center_m).norm() - o.radius_m;
  const Vec2 ab = o.point_b_m - o.point_m;
  const double s = std::clamp((c - o.point_m).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
  return (c - (o.point_m + s * ab)).norm() - o.radius_m;
}

}  // namespace internal
}  // namespace threshing_sim
