/* Shared internals of the kernels: the exact reduced line, the output sink, helpers. */
#ifndef HFTRACE_WALK_H
#define HFTRACE_WALK_H

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <math.h>
#include "core/hftrace.h"
#include "surfaces/cell_test.h"

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
    if (*status != HF_OK || !nonempty) return 0;
    *f = hf_frame_of(L);
    hf_cull_begin_reduced(c, s, mode, f, L->a0, L->b0, runs);
    return 1;
}

#define HF_DEFINE_BATCH(NAME, WALK)                                        \
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
    int NAME##_hit(hf_batch *b, hf_sink *sink, void *ctx) {                \
        return WALK(b, 0, sink, HF_MODE_HIT, ctx);                         \
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
