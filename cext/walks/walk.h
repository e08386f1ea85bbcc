/* Shared internals of the kernels: the exact reduced line, the output sink, helpers. */
#ifndef HFTRACE_WALK_H
#define HFTRACE_WALK_H

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <math.h>
#include "core/hftrace.h"
#include "surfaces/cell_test.h"
#include "surfaces/run_test.h"

/* A private mode: first hits. The sink hands each cell or run to an hf_hit, which may
 * end the walk. */
#define HF_MODE_HIT 5

#if defined(__GNUC__) || defined(__clang__)
#define HF_INLINE static inline __attribute__((always_inline))
#define HF_UNUSED __attribute__((unused))
#else
#define HF_INLINE static inline
#define HF_UNUSED
#endif

#ifndef __SIZEOF_INT128__
#error "hftrace's exact kernels need a compiler with 128-bit integers (GCC or Clang)"
#endif
__extension__ typedef __int128 hf_i128;

/* Floor division for 128-bit integers, den > 0 (defined at the end). */
HF_INLINE hf_i128 hf_floor_div(hf_i128 num, hf_i128 den);

/* Debug builds (HFTRACE_DEBUG=1) check invariants and print the values that broke them. */
#ifdef HF_DEBUG
#define HF_ASSERT(cond, fmt, ...)                                                         \
    do {                                                                                  \
        if (!(cond)) {                                                                    \
            fprintf(stderr, "hftrace assertion failed at %s:%d: %s: " fmt "\n", __FILE__, \
                    __LINE__, #cond, __VA_ARGS__);                                        \
            abort();                                                                      \
        }                                                                                 \
    } while (0)
#else
#define HF_ASSERT(cond, fmt, ...) ((void)0)
#endif

/* ---- The exact line in its reduced frame ------------------------------------------
 * Every exact kernel works in one octant: travel is along +major, the minor index never
 * decreases, and both axes use the forward half-open rule [k, k+1). Mirroring an axis
 * maps the "(i, i+1] for negative travel" rule onto that rule, so one walk serves all 8
 * octants. Positions are integers in lattice units (2^-16 cell).
 *   major(tau) = o_major + tau * time_major
 *   the line:  minor = o_minor + (major - o_major) * slope_minor / slope_major
 * For the exact kernels slope_major == time_major; runs_periodic replaces the slope by a
 * rational approximation and keeps time_major, so tmin/tmax keep their meaning along the
 * major axis. */
typedef struct {
    int swap; /* 1: the major axis is y                           */
    int mirror_major, mirror_minor;
    int32_t n_major, n_minor; /* grid extent in cells along each reduced axis     */
    int64_t o_major, o_minor; /* reduced origin in lattice units                  */
    int64_t time_major;       /* d(major)/dtau in lattice units                   */
    int64_t slope_major;      /* A > 0                                            */
    int64_t slope_minor;      /* B, 0 <= B <= A                                   */
    int32_t a0, b0, a1, b1;   /* first and last visited cell, reduced indices     */
    int scale;                /* the direction's lattice scale s: D = d 2^s rounded */
} hf_line;

/* Set up the exact line of one ray. max_denominator > 0 selects the runs_periodic slope
 * approximation. Returns 1 if the ray visits at least one cell, 0 if it visits none. */
int hf_line_exact(const double origin[2], const double direction[2], double tmin, double tmax,
                  int32_t nx, int32_t ny, int64_t max_denominator, hf_line *line);

/* The exact line's per-direction share: the lattice scale, octant and
 * slope of one rounded direction (with runs_periodic's best rational for
 * max_denominator > 0), set up once and reused while consecutive rays of a batch share
 * the direction bit for bit (parallel rays: shadows, orthographic views). */
struct hf_direction {
    double key[2]; /* the direction it was set up for, and its max_denominator */
    int64_t key_max_denominator;
    int valid, vertical;
    int scale, swap, mirror_major, mirror_minor;
    int64_t time_major, slope_major, slope_minor;
};
typedef struct hf_direction hf_direction;

/* The rounding of a ray onto the lattice (lattice.c; also declared in core/hftrace.h,
 * where the bindings take it): what the walks' band compares the caller's ray with. */
void hf_quantize_ray(const double origin[2], const double direction[2], double origin_out[2],
                     double direction_out[2]);

/* hf_line_exact with the direction's share kept in `shared` (lattice.c). */
int hf_line_shared(hf_direction *shared, const double origin[2], const double direction[2],
                   double tmin, double tmax, int32_t nx, int32_t ny, int64_t max_denominator,
                   hf_line *line);

/* ---- Output sink --------------------------------------------------------------------
 * Kernels report cells (cell kernels) or runs (run kernels); the sink turns either into
 * what the mode asks for. The mode is a compile-time constant at every call site, so
 * the switch folds away. */
typedef struct {
    int32_t *out;     /* CELLS/RUNS: next free row                                */
    int32_t *out_end; /* one past the last row this ray may write                 */
    int64_t n_cells, n_runs;
    uint64_t hash;
    int major_is_x; /* which index is the major one, for run assembly           */
    int run_open;   /* cell kernels: a run is being assembled                   */
    int32_t run_minor, run_first, run_last;
    int overflow;
    hf_hit *hit; /* HF_MODE_HIT only; set by the caller, kept by hf_sink_init  */
} hf_sink;

/* Checksum fold: a rotate-xor chain. It depends on every value and on their order, and
 * a compiler cannot collapse it into a closed form, so no kernel can skip cells. */
HF_INLINE uint64_t hf_fold(uint64_t hash, uint64_t key) {
    return ((hash << 7) | (hash >> 57)) ^ key;
}

HF_INLINE uint64_t hf_cell_key(int32_t i, int32_t j) {
    return ((uint64_t)(uint32_t)i << 32) | (uint64_t)(uint32_t)j;
}

HF_INLINE uint64_t hf_run_key(int32_t minor, int32_t first, int32_t last) {
    return ((uint64_t)(uint32_t)minor << 40) ^ ((uint64_t)(uint32_t)first << 20) ^
           (uint64_t)(uint32_t)last ^ 0x9E3779B97F4A7C15ULL;
}

HF_INLINE void hf_sink_init(hf_sink *s, int32_t *out, int32_t *out_end, int major_is_x) {
    s->out = out;
    s->out_end = out_end;
    s->n_cells = 0;
    s->n_runs = 0;
    s->hash = 0;
    s->major_is_x = major_is_x;
    s->run_open = 0;
    s->run_minor = s->run_first = s->run_last = 0;
    s->overflow = 0;
}

/* A whole run (minor, first, last), first and last in travel order along the major axis.
 * Returns 1 when the walk must stop (a first hit was found). */
HF_INLINE int hf_emit_run(hf_sink *s, const int mode, int32_t minor, int32_t first, int32_t last) {
    const int32_t step = last >= first ? 1 : -1;
    int32_t major;
    switch (mode) {
    case HF_MODE_HIT: return hf_hit_run(s->hit, s->major_is_x, minor, first, last);
    case HF_MODE_COUNT:
        s->n_runs += 1;
        s->n_cells += (int64_t)(last - first) * step + 1;
        break;
    case HF_MODE_RUNS:
        if (s->out + 3 > s->out_end) {
            s->overflow = 1;
            return 0;
        }
        s->out[0] = minor;
        s->out[1] = first;
        s->out[2] = last;
        s->out += 3;
        s->n_runs += 1;
        break;
    case HF_MODE_RUNFOLD:
        s->hash = hf_fold(s->hash, hf_run_key(minor, first, last));
        s->n_runs += 1;
        break;
    case HF_MODE_CELLS:
        /* bounds: the whole run must fit before anything is written */
        if (s->out + 2 * ((int64_t)(last - first) * step + 1) > s->out_end) {
            s->overflow = 1;
            return 0;
        }
        for (major = first;; major += step) {
            if (s->major_is_x) {
                s->out[0] = major;
                s->out[1] = minor;
            } else {
                s->out[0] = minor;
                s->out[1] = major;
            }
            s->out += 2;
            if (major == last) break;
        }
        s->n_cells += (int64_t)(last - first) * step + 1;
        break;
    case HF_MODE_VISIT:
        for (major = first;; major += step) {
            s->hash = s->major_is_x ? hf_fold(s->hash, hf_cell_key(major, minor))
                                    : hf_fold(s->hash, hf_cell_key(minor, major));
            if (major == last) break;
        }
        s->n_cells += (int64_t)(last - first) * step + 1;
        break;
    default: break;
    }
    return 0;
}

/* One cell (i, j) from a cell kernel. Run-based modes assemble runs from the cells.
 * Returns 1 when the walk must stop (a first hit was found). */
HF_INLINE int hf_emit_cell(hf_sink *s, const int mode, int32_t i, int32_t j) {
    int32_t minor, major;
    switch (mode) {
    case HF_MODE_HIT: return hf_hit_cell(s->hit, i, j);
    case HF_MODE_CELLS:
        if (s->out + 2 > s->out_end) {
            s->overflow = 1;
            return 0;
        }
        s->out[0] = i;
        s->out[1] = j;
        s->out += 2;
        s->n_cells += 1;
        return 0;
    case HF_MODE_VISIT:
        s->hash = hf_fold(s->hash, hf_cell_key(i, j));
        s->n_cells += 1;
        return 0;
    default: break;
    }
    /* COUNT, RUNS, RUNFOLD: a new run starts whenever the minor index changes */
    minor = s->major_is_x ? j : i;
    major = s->major_is_x ? i : j;
    if (s->run_open && minor == s->run_minor) {
        s->run_last = major;
        return 0;
    }
    if (s->run_open) hf_emit_run(s, mode, s->run_minor, s->run_first, s->run_last);
    s->run_open = 1;
    s->run_minor = minor;
    s->run_first = s->run_last = major;
    return 0;
}

/* ---- first hits: the cull in the walk's registers ------------------------------------
 * In HF_MODE_HIT a walk copies the per-ray invariants of the cheap bound (cell_test.h,
 * "the tight path") into this local struct, so they stay in registers across the loop
 * (the out-of-line surface test would otherwise force every field to be reloaded per
 * cell), and counts visited cells here. Only cells that survive reach hf_hit. */
/* In HF_MODE_HIT: the carried bound of cell_test.h starting at cell (i, j); runs: for a run
 * kernel (its tight path needs descending rays). Other modes: nothing. */
HF_INLINE void hf_cull_begin(hf_cull *c, const hf_sink *s, const int mode, int32_t i, int32_t j,
                             int runs) {
    c->fast = 0;
    c->visited = 0;
    if (mode == HF_MODE_HIT) hf_cull_init(c, s->hit, i, j, runs);
}

HF_INLINE void hf_cull_end(hf_cull *c, hf_sink *s, const int mode) {
    if (mode == HF_MODE_HIT) s->hit->cells_visited += c->visited;
}

/* A cell kernel stepped along axis a (0 x, 1 y) in its travel direction. */
HF_INLINE void hf_cull_walk(hf_cull *c, const int mode, int a) {
    if (mode == HF_MODE_HIT) hf_cull_step(c, a);
}

/* A cell from a cell kernel: rejected by the bound, or handed on. */
HF_INLINE int hf_visit_cell(hf_sink *s, const int mode, hf_cull *c, int32_t i, int32_t j) {
    if (mode == HF_MODE_HIT) {
        /* the walk's cell is the cull's */
        HF_ASSERT(i == c->k[0] && j == c->k[1] && c->cell == (int64_t)j * c->stride + i,
                  "walk (%d, %d) cull (%d, %d)", i, j, c->k[0], c->k[1]);
        c->visited += 1;
        if (hf_cull_zlow(c) > (double)c->cellmax[c->cell]) return 0;
        return c->fast ? hf_hit_cell_exact(s->hit, i, j) : hf_hit_cell_uncounted(s->hit, i, j);
    }
    return hf_emit_cell(s, mode, i, j);
}

/* Close the run a cell kernel was assembling. */
HF_INLINE void hf_sink_finish(hf_sink *s, const int mode) {
    if ((mode == HF_MODE_COUNT || mode == HF_MODE_RUNS || mode == HF_MODE_RUNFOLD) && s->run_open) {
        hf_emit_run(s, mode, s->run_minor, s->run_first, s->run_last);
        s->run_open = 0;
    }
}

/* ---- From the reduced frame back to grid indices ------------------------------------ */
typedef struct {
    int32_t base_major, sign_major, base_minor, sign_minor;
    int swap;
} hf_frame;

HF_INLINE hf_frame hf_frame_of(const hf_line *L) {
    hf_frame f;
    f.base_major = L->mirror_major ? L->n_major - 1 : 0;
    f.sign_major = L->mirror_major ? -1 : 1;
    f.base_minor = L->mirror_minor ? L->n_minor - 1 : 0;
    f.sign_minor = L->mirror_minor ? -1 : 1;
    f.swap = L->swap;
    return f;
}

HF_INLINE int hf_emit_reduced_cell(hf_sink *s, const int mode, const hf_frame *f, int32_t a,
                                   int32_t b) {
    const int32_t major = f->base_major + f->sign_major * a;
    const int32_t minor = f->base_minor + f->sign_minor * b;
    return f->swap ? hf_emit_cell(s, mode, minor, major) : hf_emit_cell(s, mode, major, minor);
}

HF_INLINE int hf_emit_reduced_run(hf_sink *s, const int mode, const hf_frame *f, int32_t b,
                                  int32_t first, int32_t last) {
    return hf_emit_run(s, mode, f->base_minor + f->sign_minor * b,
                       f->base_major + f->sign_major * first, f->base_major + f->sign_major * last);
}

/* hf_cull_begin at the reduced cell (a, b). */
HF_INLINE void hf_cull_begin_reduced(hf_cull *c, const hf_sink *s, const int mode,
                                     const hf_frame *f, int32_t a, int32_t b, int runs) {
    const int32_t major = f->base_major + f->sign_major * a;
    const int32_t minor = f->base_minor + f->sign_minor * b;
    if (f->swap)
        hf_cull_begin(c, s, mode, minor, major, runs);
    else
        hf_cull_begin(c, s, mode, major, minor, runs);
}

HF_INLINE int hf_visit_reduced_cell(hf_sink *s, const int mode, hf_cull *c, const hf_frame *f,
                                    int32_t a, int32_t b) {
    if (mode == HF_MODE_HIT) {
        /* the cull carries the cell's grid indices; no mapping per cell */
        HF_ASSERT(c->k[f->swap] == f->base_major + f->sign_major * a &&
                      c->k[!f->swap] == f->base_minor + f->sign_minor * b,
                  "reduced (%d, %d) cull (%d, %d)", a, b, c->k[0], c->k[1]);
        return hf_visit_cell(s, mode, c, c->k[0], c->k[1]);
    }
    {
        const int32_t major = f->base_major + f->sign_major * a;
        const int32_t minor = f->base_minor + f->sign_minor * b;
        return f->swap ? hf_visit_cell(s, mode, c, minor, major)
                       : hf_visit_cell(s, mode, c, major, minor);
    }
}

/* A run from a run kernel; in HF_MODE_HIT with the cull's tight path. */
HF_INLINE int hf_visit_reduced_run(hf_sink *s, const int mode, hf_cull *c, const hf_frame *f,
                                   int32_t b, int32_t first, int32_t last) {
    if (mode == HF_MODE_HIT && c->fast) {
        return hf_hit_run_tight(s->hit, c, s->major_is_x, f->base_minor + f->sign_minor * b,
                                f->base_major + f->sign_major * first,
                                f->base_major + f->sign_major * last);
    }
    return hf_emit_reduced_run(s, mode, f, b, first, last);
}

/* The ray's inputs, with the documented defaults for a missing tmin/tmax. */
HF_INLINE double hf_tmin(const hf_batch *b, int64_t ray) {
    return b->tmin ? b->tmin[ray] : 0.0;
}
HF_INLINE double hf_tmax(const hf_batch *b, int64_t ray) {
    return b->tmax ? b->tmax[ray] : (double)INFINITY;
}

/* ---- Batch driver -------------------------------------------------------------------
 * HF_DEFINE_BATCH(name, walk) defines int name(hf_batch *, int mode, void *ctx) that runs
 * walk(batch, ray, sink, mode, ctx) over every ray. walk must be an HF_INLINE function;
 * each mode gets its own copy of the loop with the mode folded in as a constant. */
HF_INLINE int hf_ray_begin(hf_batch *b, int64_t ray, hf_sink *s, const int mode, int major_is_x) {
    int32_t *out = NULL, *out_end = NULL;
    if (mode == HF_MODE_CELLS || mode == HF_MODE_RUNS) {
        const int64_t width = mode == HF_MODE_CELLS ? 2 : 3;
        const int64_t lo = b->offsets[ray], hi = b->offsets[ray + 1];
        if (lo < 0 || hi < lo || hi > b->out_rows) return HF_ERR_CAPACITY;
        out = b->out + lo * width;
        out_end = b->out + hi * width;
    }
    hf_sink_init(s, out, out_end, major_is_x);
    return HF_OK;
}

HF_INLINE int hf_ray_end(hf_batch *b, int64_t ray, hf_sink *s, const int mode) {
    hf_sink_finish(s, mode);
    if (s->overflow) return HF_ERR_CAPACITY;
    switch (mode) {
    case HF_MODE_COUNT:
        b->n_cells[ray] = s->n_cells;
        b->n_runs[ray] = s->n_runs;
        break;
    case HF_MODE_CELLS:
    case HF_MODE_RUNS:
        /* the counting pass and this pass must agree row for row */
        if (s->out != s->out_end) return HF_ERR_CAPACITY;
        break;
    default: b->checksums[ray] = s->hash; break;
    }
    return HF_OK;
}

/* ---- first hits of rays off the lattice: the band ----------------------------------
 * The exact walks enumerate the cells of the ray rounded onto the lattice (lattice.c);
 * the surface tests clip the caller's ray to each cell, and the first hit is defined on
 * the caller's ray (docs/CONVENTIONS.md, "Exactness", "The first hit"). Where the two
 * rays lie on different sides of a grid line, a cell the caller's ray crosses may be
 * missing from the walk. In the reduced frame (major x, minor y, the walked line
 * y(x) = y0 + (x - x0) B/A), the caller's ray p + t q deviates from the walked line at
 * its own major coordinate by
 *     y_c(t) - y(x_c(t)) = [(p_y - y0) - (p_x - x0) B/A] + t [q_y - q_x B/A],
 * so |deviation| <= eps = |first| + max(|t0|, |t1|) |second| over the walk's [t0, t1]
 * (computed in float64 and inflated by a bound on its own rounding). Every cell the
 * caller's ray crosses therefore lies in the band: cells (a, b) with some x in [a, a+1)
 * where y(x) is within eps of [b, b+1], and inside the rectangle [alo, ahi] x [blo, bhi]
 * that holds the caller's ray itself (its own clipped end points, padded by their
 * rounding). Row b of the band is the run
 *     [floor((N(b) - thr) / W), floor((N(b+1) + thr) / W)],   thr >= eps A 2^16,
 * with N(b) / W the walked line's crossing of y = b (runs.c's exact crossing, W = B 2^16).
 * It is the walk's run of row b widened at each end; the widening is non-empty only where
 * the crossing's remainder R is within thr of a column line (R < thr on the left;
 * R == 0 or R > W - thr on the right), which the walks test per run (per row step in
 * midpoint): one to three compares per run when the ray is off the lattice, none when it
 * is on it (eps == 0: the band is off and the walks are the lattice walks, bit for bit).
 *
 * Order. The caller's ray crosses the rows in increasing b (B > 0 implies q_y > 0 in the
 * reduced frame) and the columns of a row in increasing a, so listing the band row by
 * row, each row from left to right, lists the cells the caller's ray crosses in order of
 * t; a listed cell the caller's ray does not cross has an empty interval and is not hit.
 * So the first hit found is still the first hit, and the walks stop there: no earlier
 * cell of the caller's ray can remain untested, because every one of them lies in an
 * earlier row of the band or earlier in the same row, both listed before.
 * A rounded ray parallel to the major axis (B == 0, a vertical ray too) lists the
 * rectangle row by row in the caller's own direction along y. A rounded ray that meets
 * no cell lists the caller's rectangle in grid order (hf_band_empty). */
typedef struct {
    int on;            /* 0: the caller's ray is the walked line                        */
    int full;          /* eps too wide for the thresholds: every row's band is [alo, ahi] */
    int rows_down;     /* B == 0: the caller's y decreases in the reduced frame          */
    int wide;          /* thr >= W: a row's band reaches past its neighbouring columns   */
    int64_t thr;       /* eps A 2^16 rounded up, in the units of the crossing N          */
    int64_t W;         /* B 2^16                                                         */
    int64_t right_cut; /* W - thr: a larger end remainder widens a run */
    int32_t alo, ahi, blo, bhi; /* the caller's rectangle, reduced indices      */
} hf_band;

/* floor(x) clamped into [0, n - 1] (NaN: 0), without a libm call: x is positive and
 * below n - 1 where it truncates. */
HF_INLINE int32_t hf_band_floor(double x, int32_t n) {
    if (!(x > 0)) return 0;
    return x >= (double)(n - 1) ? n - 1 : (int32_t)x;
}

/* The caller's cells along one axis (n cells): [*lo, *hi], from its clipped ends padded
 * by their rounding; an exact start (t0 == 0) and a zero component by the forward rule
 * ([k, k+1) moving forward or standing, (k, k+1] moving back). */
HF_INLINE void hf_band_axis(double p, double q, double t0, double t1, int32_t n, int32_t *lo,
                            int32_t *hi) {
    if (q == 0) {
        *lo = *hi = hf_band_floor(p, n);
        return;
    }
    {
        const double x0 = p + t0 * q, x1 = p + t1 * q;
        const double mu = (fabs(p) + fabs(t0 * q) + fabs(t1 * q)) * 0x1p-48;
        *lo = hf_band_floor((x0 < x1 ? x0 : x1) - mu, n);
        *hi = hf_band_floor((x0 < x1 ? x1 : x0) + mu, n);
        if (t0 == 0 && q > 0) *lo = hf_band_floor(p, n);
        if (t0 == 0 && q < 0) {
            /* (k, k+1]: p itself when it is an integer k + 1 > 0 */
            const int32_t k = hf_band_floor(p, n);
            *hi = (p > 0 && p < (double)n && p == (double)k) ? (k > 0 ? k - 1 : 0) : k;
        }
        if (*hi < *lo) *hi = *lo;
    }
}

/* The band of the caller's ray (h) around the walked line L (non-empty). */
HF_COLD void hf_band_init(hf_band *bd, const hf_hit *h, const hf_line *L) {
    const int M = L->swap;
    const double sM = L->mirror_major ? -1.0 : 1.0, sm = L->mirror_minor ? -1.0 : 1.0;
    const double pM = M ? h->oy : h->ox, pm = M ? h->ox : h->oy;
    const double qM = (M ? h->dy : h->dx) * sM, qm = (M ? h->dx : h->dy) * sm;
    const double unit = 1.0 / (double)HF_ONE;
    /* the walked origin, unmirrored (exact: integers below 2^53, scaled by 2^-16) */
    const double OM =
        (double)(L->mirror_major ? (int64_t)L->n_major * HF_ONE - L->o_major : L->o_major) * unit;
    const double Om =
        (double)(L->mirror_minor ? (int64_t)L->n_minor * HF_ONE - L->o_minor : L->o_minor) * unit;
    const double dM = (pM - OM) * sM, dm = (pm - Om) * sm;
    const double A = (double)L->slope_major, B = (double)L->slope_minor, k = B / A;
    const double T = fabs(h->t0) > fabs(h->t1) ? fabs(h->t0) : fabs(h->t1);
    double eps, scaled;
    int32_t ilo, ihi, jlo, jhi;
    bd->on = 0;
    if (dM == 0 && dm == 0) {
        /* on the lattice when the direction is the walked one exactly: q 2^s integers
         * with q_x 2^s = time_major and q_y 2^s / (q_x 2^s) = B / A */
        const double DM = ldexp(qM, L->scale), Dm = ldexp(qm, L->scale);
        if (DM == (double)L->time_major && fabs(Dm) < 0x1p53 && Dm == (double)(int64_t)Dm &&
            (hf_i128)(int64_t)Dm * L->slope_major == (hf_i128)L->slope_minor * L->time_major)
            return;
        if (qM == 0 && qm == 0) return; /* vertical, on the lattice */
    }
    bd->on = 1;
    eps = fabs(dm - dM * k) + T * fabs(qm - qM * k);
    eps += (fabs(dm) + fabs(dM) * k + T * (fabs(qm) + fabs(qM) * k)) * 0x1p-46 + 0x1p-1000;
    scaled = eps * A * (double)HF_ONE; /* thr */
    bd->W = L->slope_minor * HF_ONE;
    bd->full = !(scaled < 0x1p60);
    bd->thr = bd->full ? ((int64_t)1 << 61) : (int64_t)scaled + 2; /* > scaled */
    bd->wide = bd->thr >= bd->W;
    bd->right_cut = bd->W - bd->thr;
    bd->rows_down = qm < 0;
    hf_band_axis(h->ox, h->dx, h->t0, h->t1, h->cols - 1, &ilo, &ihi);
    hf_band_axis(h->oy, h->dy, h->t0, h->t1, h->rows - 1, &jlo, &jhi);
    {
        const int32_t lo_M = M ? jlo : ilo, hi_M = M ? jhi : ihi;
        const int32_t lo_m = M ? ilo : jlo, hi_m = M ? ihi : jhi;
        bd->alo = L->mirror_major ? L->n_major - 1 - hi_M : lo_M;
        bd->ahi = L->mirror_major ? L->n_major - 1 - lo_M : hi_M;
        bd->blo = L->mirror_minor ? L->n_minor - 1 - hi_m : lo_m;
        bd->bhi = L->mirror_minor ? L->n_minor - 1 - lo_m : hi_m;
    }
}

/* Reduced cells lo..hi of row b, each by the general cell path. Returns 1 on a hit. */
HF_COLD int hf_band_cells(hf_sink *s, const hf_frame *f, int32_t b, int32_t lo, int32_t hi) {
    int32_t a;
    for (a = lo; a <= hi; ++a) {
        const int32_t major = f->base_major + f->sign_major * a;
        const int32_t minor = f->base_minor + f->sign_minor * b;
        if (f->swap ? hf_hit_cell(s->hit, minor, major) : hf_hit_cell(s->hit, major, minor))
            return 1;
    }
    return 0;
}

HF_INLINE int64_t hf_floor_div64(int64_t n, int64_t d) {
    const int64_t q = n / d;
    return (n % d != 0 && n < 0) ? q - 1 : q;
}

/* Row b's band widened to the left of `first`, the row's crossing being column c with
 * remainder R (N(b) = c W + R). Returns 1 on a hit. */
HF_COLD int hf_band_left(hf_sink *s, const hf_frame *f, const hf_band *bd, int32_t b, int32_t first,
                         int64_t c, int64_t R) {
    int64_t lo = bd->full ? bd->alo : c + hf_floor_div64(R - bd->thr, bd->W);
    if (lo < bd->alo) lo = bd->alo;
    return lo < first ? hf_band_cells(s, f, b, (int32_t)lo, first - 1) : 0;
}

/* Row b's band widened to the right of `last`, the crossing into row b + 1 being column
 * c with remainder R. Returns 1 on a hit. */
HF_COLD int hf_band_right(hf_sink *s, const hf_frame *f, const hf_band *bd, int32_t b, int32_t last,
                          int64_t c, int64_t R) {
    int64_t hi = bd->full ? bd->ahi : c + hf_floor_div64(R + bd->thr, bd->W);
    if (hi > bd->ahi) hi = bd->ahi;
    return hi > last ? hf_band_cells(s, f, b, last + 1, (int32_t)hi) : 0;
}

/* The crossing of the walked line into row b: N(b) = c W + R. */
HF_INLINE void hf_band_crossing(const hf_line *L, int64_t b, int64_t *c, int64_t *R) {
    const hf_i128 W = (hf_i128)L->slope_minor * HF_ONE;
    const hf_i128 N =
        (hf_i128)L->o_major * L->slope_minor + ((hf_i128)b * HF_ONE - L->o_minor) * L->slope_major;
    const hf_i128 q = hf_floor_div(N, W);
    *c = (int64_t)q;
    *R = (int64_t)(N - q * W);
}

/* The whole band row b (outside the walk's rows). Returns 1 on a hit. */
HF_COLD int hf_band_row(hf_sink *s, const hf_frame *f, const hf_line *L, const hf_band *bd,
                        int32_t b) {
    int64_t c, R, lo = bd->alo, hi = bd->ahi;
    if (!bd->full) {
        hf_band_crossing(L, b, &c, &R);
        lo = c + hf_floor_div64(R - bd->thr, bd->W);
        hf_band_crossing(L, (int64_t)b + 1, &c, &R);
        hi = c + hf_floor_div64(R + bd->thr, bd->W);
    }
    if (lo < bd->alo) lo = bd->alo;
    if (hi > bd->ahi) hi = bd->ahi;
    return lo <= hi ? hf_band_cells(s, f, b, (int32_t)lo, (int32_t)hi) : 0;
}

/* Before the walk's first run (B > 0): the band rows below b0, then row b0 left of a0. */
HF_COLD int hf_band_start_cold(hf_sink *s, const hf_frame *f, const hf_line *L, const hf_band *bd) {
    int32_t b;
    int64_t c, R;
    for (b = bd->blo; b < L->b0; ++b)
        if (hf_band_row(s, f, L, bd, b)) return 1;
    if (bd->alo >= L->a0) return 0;
    hf_band_crossing(L, L->b0, &c, &R);
    return hf_band_left(s, f, bd, L->b0, L->a0, c, R);
}

/* After the walk's last run (B > 0): row b1 right of a1, then the band rows above b1. */
HF_COLD int hf_band_end_cold(hf_sink *s, const hf_frame *f, const hf_line *L, const hf_band *bd) {
    int32_t b;
    if (bd->ahi > L->a1) {
        int64_t c, R;
        hf_band_crossing(L, (int64_t)L->b1 + 1, &c, &R);
        if (hf_band_right(s, f, bd, L->b1, L->a1, c, R)) return 1;
    }
    for (b = L->b1 + 1; b <= bd->bhi; ++b)
        if (hf_band_row(s, f, L, bd, b)) return 1;
    return 0;
}

/* The two above, out of line only when the caller's rectangle reaches past the walk's
 * first (last) cell: a compare or two per ray otherwise. */
HF_INLINE int hf_band_start(hf_sink *s, const hf_frame *f, const hf_line *L, const hf_band *bd) {
    return (bd->blo < L->b0 || bd->alo < L->a0) && hf_band_start_cold(s, f, L, bd);
}

HF_INLINE int hf_band_end(hf_sink *s, const hf_frame *f, const hf_line *L, const hf_band *bd) {
    return (bd->bhi > L->b1 || bd->ahi > L->a1) && hf_band_end_cold(s, f, L, bd);
}

/* A walked line parallel to the major axis (B == 0; a vertical ray too): the caller's
 * rectangle, row by row in its own direction along the minor axis. */
HF_COLD void hf_band_straight(hf_sink *s, const hf_frame *f, const hf_band *bd) {
    int32_t b;
    if (bd->rows_down) {
        for (b = bd->bhi; b >= bd->blo; --b)
            if (hf_band_cells(s, f, b, bd->alo, bd->ahi)) return;
    } else {
        for (b = bd->blo; b <= bd->bhi; ++b)
            if (hf_band_cells(s, f, b, bd->alo, bd->ahi)) return;
    }
}

/* A rounded ray that meets no cell while the caller's ray (h) may: unless the caller's
 * ray is the rounded one, its rectangle cell by cell, rows in its direction along y and
 * columns along x (the order of t, as above). `origin`: the walk's 2D origin. */
HF_COLD void hf_band_empty(hf_hit *h) {
    const double o[2] = {h->ox, h->oy}, d[2] = {h->dx, h->dy};
    double oq[2], dq[2];
    int32_t ilo, ihi, jlo, jhi, i, j;
    hf_quantize_ray(o, d, oq, dq);
    if (oq[0] == o[0] && oq[1] == o[1] && dq[0] == d[0] && dq[1] == d[1]) return;
    hf_band_axis(h->ox, h->dx, h->t0, h->t1, h->cols - 1, &ilo, &ihi);
    hf_band_axis(h->oy, h->dy, h->t0, h->t1, h->rows - 1, &jlo, &jhi);
    for (j = h->dy < 0 ? jhi : jlo; h->dy < 0 ? j >= jlo : j <= jhi; j += h->dy < 0 ? -1 : 1)
        for (i = h->dx < 0 ? ihi : ilo; h->dx < 0 ? i >= ilo : i <= ihi; i += h->dx < 0 ? -1 : 1)
            if (hf_hit_cell(h, i, j)) return;
}

/* The shared start of the exact walks: the exact line (max_denominator > 0: the
 * runs_periodic slope), the sink, the frame and, in HF_MODE_HIT, the carried bound at the
 * first cell. Returns 1 with *status = HF_OK to walk; 0 to return *status (an error, or a
 * ray that visits no cell). */
HF_INLINE int hf_exact_begin(hf_batch *b, int64_t ray, hf_sink *s, const int mode,
                             int64_t max_denominator, int runs, hf_line *L, hf_frame *f, hf_cull *c,
                             int *status) {
    /* the per-direction set-up: shared with the previous ray when the batch keeps one */
    const int nonempty =
        b->direction_cache != NULL
            ? hf_line_shared(b->direction_cache, b->origins + 2 * ray, b->directions + 2 * ray,
                             hf_tmin(b, ray), hf_tmax(b, ray), b->nx, b->ny, max_denominator, L)
            : hf_line_exact(b->origins + 2 * ray, b->directions + 2 * ray, hf_tmin(b, ray),
                            hf_tmax(b, ray), b->nx, b->ny, max_denominator, L);
    *status = hf_ray_begin(b, ray, s, mode, !L->swap);
    if (*status != HF_OK) return 0;
    if (!nonempty) {
        /* the rounded ray meets no cell: the caller's ray may still (hf_band_empty) */
        if (mode == HF_MODE_HIT) hf_band_empty(s->hit);
        return 0;
    }
    *f = hf_frame_of(L);
    hf_cull_begin_reduced(c, s, mode, f, L->a0, L->b0, runs);
    return 1;
}

#define HF_DEFINE_BATCH_MODES(NAME, WALK)                                  \
    HF_INLINE int NAME##_loop(hf_batch *b, const int mode, void *ctx) {    \
        int64_t ray;                                                       \
        int status = HF_OK;                                                \
        hf_sink sink;                                                      \
        hf_direction shared;                                               \
        struct hf_direction *caller_cache = b->direction_cache;            \
        shared.valid = 0;                                                  \
        if (caller_cache == NULL) b->direction_cache = &shared;            \
        for (ray = 0; ray < b->n_rays; ++ray) {                            \
            status = WALK(b, ray, &sink, mode, ctx);                       \
            if (status == HF_OK) status = hf_ray_end(b, ray, &sink, mode); \
            if (status != HF_OK) {                                         \
                b->bad_ray = ray;                                          \
                break;                                                     \
            }                                                              \
        }                                                                  \
        b->direction_cache = caller_cache;                                 \
        return status;                                                     \
    }                                                                      \
    int NAME(hf_batch *b, int mode, void *ctx) {                           \
        switch (mode) {                                                    \
        case HF_MODE_COUNT: return NAME##_loop(b, HF_MODE_COUNT, ctx);     \
        case HF_MODE_CELLS: return NAME##_loop(b, HF_MODE_CELLS, ctx);     \
        case HF_MODE_RUNS: return NAME##_loop(b, HF_MODE_RUNS, ctx);       \
        case HF_MODE_VISIT: return NAME##_loop(b, HF_MODE_VISIT, ctx);     \
        case HF_MODE_RUNFOLD: return NAME##_loop(b, HF_MODE_RUNFOLD, ctx); \
        default: return HF_ERR_ARGUMENT;                                   \
        }                                                                  \
    }

/* HF_DEFINE_BATCH: the modes above and NAME_hit, the walk in HF_MODE_HIT. A kernel whose
 * first-hit walk is written apart (midpoint.c) takes HF_DEFINE_BATCH_MODES alone and
 * defines NAME_hit itself, so that its other modes compile exactly as before. */
#define HF_DEFINE_BATCH(NAME, WALK)                         \
    HF_DEFINE_BATCH_MODES(NAME, WALK)                       \
    int NAME##_hit(hf_batch *b, hf_sink *sink, void *ctx) { \
        return WALK(b, 0, sink, HF_MODE_HIT, ctx);          \
    }

int hf_batch_dda(hf_batch *b, int mode, void *ctx);
int hf_batch_dda_f32(hf_batch *b, int mode, void *ctx);
int hf_batch_midpoint(hf_batch *b, int mode, void *ctx);
int hf_batch_runs(hf_batch *b, int mode, void *ctx);
int hf_batch_runs_f64(hf_batch *b, int mode, void *ctx);
int hf_batch_runs_periodic(hf_batch *b, int mode, void *ctx);

/* The same walks in HF_MODE_HIT: one ray (ray 0 of b), the sink's hit context decides. */
typedef int (*hf_hit_walk)(hf_batch *b, hf_sink *sink, void *ctx);
int hf_batch_dda_hit(hf_batch *b, hf_sink *sink, void *ctx);
int hf_batch_dda_f32_hit(hf_batch *b, hf_sink *sink, void *ctx);
int hf_batch_midpoint_hit(hf_batch *b, hf_sink *sink, void *ctx);
int hf_batch_runs_hit(hf_batch *b, hf_sink *sink, void *ctx);
int hf_batch_runs_f64_hit(hf_batch *b, hf_sink *sink, void *ctx);
int hf_batch_runs_periodic_hit(hf_batch *b, hf_sink *sink, void *ctx);

/* runs_maxmip: the maximum mipmap its walk skips with (level 0: the cell maxima). */
typedef struct {
    const float *const *levels;
    const int32_t *cols; /* row stride of each level */
    int n_levels;
    int floor_level; /* tiles of 2^floor_level cells are walked run by run */
} hf_mipmap;

int hf_runs_maxmip_hit(hf_batch *b, hf_sink *sink, const hf_mipmap *m);

/* runs_periodic keeps its pattern between the rays of a batch (the ctx above). */
typedef struct {
    int64_t p, q;          /* the pattern's slope p/q in lowest terms; q == 0: none yet */
    int64_t position_step; /* (q mod p)^-1 mod p: residue -> pattern position          */
    int32_t *lengths;      /* lengths[k]: 8-connected run length at pattern position k */
} hf_pattern;

/* Floor division for 128-bit integers, den > 0. The common cases avoid the slow 128-bit
 * division routine: both operands fitting in 64 bits, and power-of-two divisors (an
 * arithmetic right shift, which is floor division for GCC and Clang). */
HF_INLINE hf_i128 hf_floor_div(hf_i128 num, hf_i128 den) {
    hf_i128 q;
    if ((den & (den - 1)) == 0) {
        const uint64_t low = (uint64_t)den;
        const int shift = low ? __builtin_ctzll(low) : 64 + __builtin_ctzll((uint64_t)(den >> 64));
        return num >> shift;
    }
    if (num == (hf_i128)(int64_t)num && den == (hf_i128)(int64_t)den) {
        const int64_t n64 = (int64_t)num, d64 = (int64_t)den;
        int64_t q64 = n64 / d64;
        if ((n64 % d64 != 0) && (n64 < 0)) q64 -= 1;
        return q64;
    }
    {
        /* a float estimate (relative error ~2^-52), then exact correction by
         * multiplication: far cheaper than the 128-bit division routine */
        const double estimate = floor((double)num / (double)den);
        if (fabs(estimate) < 4503599627370496.0) { /* 2^52: the estimate is off by <= 2 */
            hf_i128 rem;
            q = (hf_i128)(int64_t)estimate;
            rem = num - q * den;
            while (rem < 0) {
                q -= 1;
                rem += den;
            }
            while (rem >= den) {
                q += 1;
                rem -= den;
            }
            return q;
        }
    }
    q = num / den;
    if ((num % den != 0) && (num < 0)) q -= 1;
    return q;
}

#endif
