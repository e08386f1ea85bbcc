/* hftrace: 2D grid traversal kernels for height-field ray tracing.
 *
 * Conventions (binding): docs/CONVENTIONS.md, mirrored in README.md.
 * Cell (i, j) is [i, i+1] x [j, j+1]; cells are half-open toward the direction of travel.
 *
 * The C layer trusts its arguments: the Python wrapper (algos/traverse.py) validates
 * shapes, dtypes, finiteness and the documented limits below before calling in.
 */
#ifndef HFTRACE_H
#define HFTRACE_H

#include <stdint.h>

/* ---- Documented limits (checked in Python, asserted in debug builds) ---------------- */
#define HF_FRAC_BITS               16 /* exact lattice: 2^-16 cell              */
#define HF_ONE                     ((int64_t)1 << HF_FRAC_BITS) /* one cell in lattice units              */
#define HF_MAX_GRID_SIDE           (1L << 24)   /* cells per side                         */
#define HF_MAX_ORIGIN_ABS          1073741824.0 /* |origin component| <= 2^30 cells       */
#define HF_DIR_BITS                31           /* rounded direction: max |D| in [2^30, 2^31] */
#define HF_DEFAULT_MAX_DENOMINATOR 65536        /* runs_periodic: default Q               */
#define HF_MAX_DENOMINATOR         (1L << 24)   /* runs_periodic: largest Q accepted      */

/* ---- Kernels and output modes ------------------------------------------------------ */
enum hf_kernel {
    HF_DDA = 0,           /* Amanatides & Woo 1987, float64                              */
    HF_DDA_F32 = 1,       /* the same recurrence in float32                              */
    HF_MIDPOINT = 2,      /* exact integer decision variable, one cell per step          */
    HF_RUNS = 3,          /* exact run recurrence (Henning & Stephenson 2004)            */
    HF_RUNS_F64 = 4,      /* the run recurrence in float64                               */
    HF_RUNS_PERIODIC = 5, /* exact replay of the periodic run pattern of a p/q slope     */
    HF_N_KERNELS = 6
};

/* The first-hit intersectors: the traversal kernels above (each walks the cells it tests)
 * and these. The binding exports every id by name (algos._kernels.KERNEL_IDS), so the
 * numbers are written here only. */
enum hf_hit_kernel {
    HF_HIT_DDA_MAXMIP = 6,
    HF_HIT_RUNS_MAXMIP = 7,
    HF_HIT_MARCH_LINEAR = 8,
    HF_HIT_MARCH_GROWING = 9,
    HF_HIT_MARCH_BINARY = 10,
    HF_HIT_CONE = 11,
    HF_HIT_CONE_RELAXED = 12,
    HF_HIT_PACKET_MAXMIP = 13,
    HF_HIT_DDA_COMPACT = 14,
    HF_HIT_PLANE_MAXMIP = 15,
    HF_HIT_PITCHED_MAXMIP = 16,
    HF_HIT_RING_MAXMIP = 17,
    HF_N_HIT_KERNELS = 18
};

enum hf_mode {
    HF_MODE_COUNT = 0,   /* number of cells and runs per ray                            */
    HF_MODE_CELLS = 1,   /* store every cell (i, j)                                     */
    HF_MODE_RUNS = 2,    /* store every run (minor, first, last)                        */
    HF_MODE_VISIT = 3,   /* fold every cell into a per-ray checksum (workload "visit")  */
    HF_MODE_RUNFOLD = 4, /* fold every run into a per-ray checksum (workload "runs")    */
    HF_N_MODES = 5
};

enum hf_status {
    HF_OK = 0,
    HF_ERR_CAPACITY = -1, /* an output buffer was too small (a bug in the caller)      */
    HF_ERR_INTERNAL = -2, /* an exact walk did not reach its computed last cell        */
    HF_ERR_ARGUMENT = -3, /* unknown kernel or mode                                    */
    HF_ERR_MEMORY = -4    /* a kernel or renderer could not allocate its scratch       */
};

/* One batch of rays and the buffers its mode writes to. Unused pointers may be NULL. */
typedef struct {
    int64_t n_rays;
    const double *origins;     /* (n_rays, 2), C order                                 */
    const double *directions;  /* (n_rays, 2), C order                                 */
    const double *tmin;        /* (n_rays,) or NULL for 0                              */
    const double *tmax;        /* (n_rays,) or NULL for +inf                           */
    int32_t nx, ny;            /* grid size in cells, (x, y) order                     */
    int64_t max_denominator;   /* runs_periodic: Q                                     */
    int32_t *pattern;          /* runs_periodic workspace: max_denominator + 1 entries */
    int64_t *n_cells, *n_runs; /* COUNT: per ray                                       */
    const int64_t *offsets;    /* CELLS, RUNS: (n_rays + 1,) row offsets               */
    int32_t *out;              /* CELLS: (M, 2); RUNS: (M, 3)                          */
    int64_t out_rows;          /* M, the capacity of out in rows                       */
    uint64_t *checksums;       /* VISIT, RUNFOLD: per ray                              */
    int64_t bad_ray;           /* on error: the ray that caused it                     */
    /* the exact kernels' per-direction set-up, kept across consecutive rays of one
     * direction (walks/walk.h); NULL: set up every ray afresh */
    struct hf_direction *direction_cache;
} hf_batch;

/* Run one kernel over a batch in one mode. Returns an hf_status. Thread-safe; no
 * allocation; the GIL may be released around it. */
int hf_walk_batch(int kernel, int mode, hf_batch *batch);

/* Exact rounding of a ray onto the lattice, exposed for tests: writes the rounded origin
 * and direction as doubles (exactly representable). */
void hf_quantize_ray(const double origin[2], const double direction[2], double origin_out[2],
                     double direction_out[2]);

/* Best rational approximation of num/den (0 <= num <= den, den > 0) with denominator at
 * most max_den; ties go to the smaller denominator (as Python's
 * Fraction.limit_denominator). Writes the reduced p/q. */
void hf_best_rational(int64_t num, int64_t den, int64_t max_den, int64_t *p, int64_t *q);

#endif
