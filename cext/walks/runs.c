/* Run-based traversal (Henning & Stephenson 2004): one step per run instead of per cell.
 *
 * Reduced frame: travel along +major, slope B/A with 0 <= B <= A. The line crosses the
 * minor grid line `row` at major position
 *     X(row) = o_major + (row 2^16 - o_minor) A / B            (lattice units)
 * and crossing column c(row) = floor(X(row) / 2^16). Row `row` is visited from the column
 * where the line enters it to the column where it leaves it:
 *     run(row) = (row, c(row), c(row + 1) - [X(row + 1) is a vertex]).
 * Consecutive runs share the crossing column except at an exact vertex crossing.
 *
 * The 8-connected run length c(row + 1) - c(row) is floor(A/B) (short) or that plus one
 * (long). With X(row) B = c W + R, W = B 2^16, 0 <= R < W, the step adds A 2^16 =
 * floor(A/B) W + rem, so the run is long exactly when R + rem >= W, i.e. when the
 * fractional crossing position R/W is at least 1 - frac(A/B). In the seeds' notation
 * (beta = alpha * (1 - R/W), v = 1 - alpha floor(1/alpha)) this is "beta <= v -> long":
 * the slides print the inequality the other way round; tests/walks/test_runs_math.py checks the
 * derivation on the slides' own example y = 17/41 x.
 *
 * Start clipping: the first run starts at the clipped start cell and ends at the first
 * crossing, which is computed directly with one 128-bit division; the recurrence then
 * carries (c, R) from run to run in int64 (R < 2^47). */
#include "walks/walk.h"
#include "core/mipmap.h"

/* ---- runs: the exact recurrence ------------------------------------------------------
 * The runs of a line with B = slope_minor > 0, from its start-clipped first run to its
 * last. Shared by runs and by runs_periodic for rays too short for a pattern to pay. */
HF_INLINE int runs_recurrence(hf_sink *s, const int mode, hf_cull *cull, const hf_line *L,
                              const hf_frame *f, const hf_band *bd, const int band) {
    int32_t row, first, last;
    int64_t column, R, R_in = INT64_MAX; /* R_in: the row's own crossing (none for b0) */
    const int64_t W = L->slope_minor * HF_ONE;
    const int64_t short_length = L->slope_major / L->slope_minor;
    const int64_t rem = (L->slope_major % L->slope_minor) * HF_ONE;
    {
        /* start clipping: the crossing into row b0 + 1, exactly */
        const hf_i128 N = (hf_i128)L->o_major * L->slope_minor +
                          ((hf_i128)(L->b0 + 1) * HF_ONE - L->o_minor) * L->slope_major;
        const hf_i128 c = hf_floor_div(N, W);
        column = (int64_t)c;
        R = (int64_t)(N - c * W);
    }
    first = L->a0;
    /* off the lattice (first hits): the band rows before the walk's, and each run widened
     * where its crossings lie within the band's reach of a column line (walk.h) */
    if (band && hf_band_start(s, f, L, bd)) return HF_OK;
    for (row = L->b0; row < L->b1; ++row) {
        last = (int32_t)(R == 0 ? column - 1 : column);
        HF_ASSERT(last >= first && last <= L->a1, "row=%d first=%d last=%d a1=%d", row, first, last,
                  L->a1);
        if (band && R_in < bd->thr && hf_band_left(s, f, bd, row, first, first, R_in)) return HF_OK;
        if (hf_visit_reduced_run(s, mode, cull, f, row, first, last)) return HF_OK;
        if (band && (R == 0 || R > bd->right_cut) && hf_band_right(s, f, bd, row, last, column, R))
            return HF_OK;
        first = (int32_t)column;
        if (band) R_in = R;
        column += short_length;
        R += rem;
        if (R >= W) {
            R -= W;
            column += 1;
        }
    }
    if (first > L->a1) return HF_ERR_INTERNAL;
    if (band && R_in < bd->thr && hf_band_left(s, f, bd, L->b1, first, first, R_in)) return HF_OK;
    if (hf_visit_reduced_run(s, mode, cull, f, L->b1, first, L->a1)) return HF_OK;
    if (band) hf_band_end(s, f, L, bd);
    return HF_OK;
}

/* First hits of a ray off the lattice (bd->on) over the walk's line: the band (walk.h). */
HF_INLINE int runs_band(hf_sink *s, hf_cull *cull, const hf_line *L, const hf_frame *f,
                        const hf_band *bd) {
    if (L->slope_minor == 0) {
        hf_band_straight(s, f, bd);
        return HF_OK;
    }
    return runs_recurrence(s, HF_MODE_HIT, cull, L, f, bd, 1);
}

HF_INLINE int walk_runs(hf_batch *b, int64_t ray, hf_sink *s, const int mode, void *ctx) {
    hf_line L;
    hf_frame f;
    hf_cull cull;
    hf_band bd;
    int status;
    (void)ctx;
    if (!hf_exact_begin(b, ray, s, mode, 0, 1, &L, &f, &cull, &status)) return status;
    bd.on = 0;
    if (mode == HF_MODE_HIT) hf_band_init(&bd, s->hit, &L);
    if (mode == HF_MODE_HIT && bd.on)
        status = runs_band(s, &cull, &L, &f, &bd);
    else if (L.slope_minor == 0)
        hf_visit_reduced_run(s, mode, &cull, &f, L.b0, L.a0, L.a1);
    else
        status = runs_recurrence(s, mode, &cull, &L, &f, NULL, 0);
    hf_cull_end(&cull, s, mode);
    return status;
}

HF_DEFINE_BATCH(hf_batch_runs, walk_runs)

/* ---- runs_maxmip: one exact run walker under the maximum mipmap -------------------------
 * The walker is the recurrence above, set up once per ray; the mipmap decides what it may
 * skip. From the walker's current cell the walk tests the tile around it, at level L, with
 * z at the tile's exit face (descending; else at the walk's current parameter), climbs
 * one level after a skip and descends one level when a tile cannot be skipped (Tevs et al.
 * 2008). Tiles of the floor level that cannot be skipped are walked run by run: each run
 * clipped to the tile is one segment for the tight run test. Skipping a tile moves the
 * walker past it exactly, row by row through the recurrence, or, over more than
 * HF_SEEK_ROWS rows, by computing the crossings at the target row directly. The cells the
 * walker visits are the runs kernel's, so its hits are too. */
#ifndef HF_SEEK_ROWS
#define HF_SEEK_ROWS 32
#endif

typedef struct {
    const hf_line *L;
    int32_t row, first, last, pos; /* the current run (reduced) and the current cell   */
    int64_t column, R;             /* the crossing into row + 1: column, remainder     */
    int64_t R_in;                  /* the row's own crossing remainder (b0: none, max) */
    int64_t W, short_length, rem;  /* the recurrence's constants                       */
} run_walker;

/* The crossing of the line into row k: column and remainder (k > b0). */
static void walker_crossing(const hf_line *L, int64_t k, int64_t W, int64_t *column, int64_t *R) {
    const hf_i128 N =
        (hf_i128)L->o_major * L->slope_minor + ((hf_i128)k * HF_ONE - L->o_minor) * L->slope_major;
    const hf_i128 c = hf_floor_div(N, W);
    *column = (int64_t)c;
    *R = (int64_t)(N - c * W);
}

HF_INLINE void walker_set_last(run_walker *w) {
    w->last = w->row < w->L->b1 ? (int32_t)(w->R == 0 ? w->column - 1 : w->column) : w->L->a1;
}

HF_INLINE void walker_next_row(run_walker *w) {
    w->R_in = w->R;
    w->row += 1;
    w->first = (int32_t)w->column;
    w->pos = w->first;
    w->column += w->short_length;
    w->R += w->rem;
    if (w->R >= w->W) {
        w->R -= w->W;
        w->column += 1;
    }
    walker_set_last(w);
}

/* Row k (> the current row, <= b1) directly, at cell `pos` (>= its first cell). */
static void walker_seek(run_walker *w, int32_t k, int32_t pos) {
    int64_t c, R;
    walker_crossing(w->L, k, w->W, &c, &R);
    w->R_in = R;
    w->row = k;
    w->first = (int32_t)c;
    walker_crossing(w->L, (int64_t)k + 1, w->W, &w->column, &w->R);
    walker_set_last(w);
    w->pos = pos > w->first ? pos : w->first;
}

/* The row in which the line enters column P (P <= a1, in a row after the current one). */
static int32_t walker_row_of_column(const run_walker *w, int32_t P) {
    const hf_line *L = w->L;
    const hf_i128 N =
        (hf_i128)L->o_minor * L->slope_major + ((hf_i128)P * HF_ONE - L->o_major) * L->slope_minor;
    return (int32_t)hf_floor_div(N, (hf_i128)L->slope_major * HF_ONE);
}

/* Move the walker to its first cell past the tile whose last reduced column and row are
 * cmax and rmax (the walker is inside it). Returns 1 when the line ends inside the tile,
 * 2 when a cell of the band (bd != NULL: a first hit off the lattice) was hit, else 0.
 * The tile's cull covers every cell of the caller's ray inside the tile; the band's cells
 * outside it that the skipped rows reach are tested here (the band is narrow, thr < W: a
 * run widens by at most one cell at each end, so only the row after the walker's entry
 * row can reach left of the tile, and only the row the walker leaves the tile from can
 * reach right of it, past cmax). */
static int walker_leave(run_walker *w, int32_t cmax, int32_t rmax, hf_sink *s, const hf_frame *f,
                        const hf_band *bd) {
    const hf_line *L = w->L;
    for (;;) {
        if (w->last > cmax) {
            w->pos = cmax + 1;
            return 0;
        }
        if (w->row >= L->b1) return 1;
        if ((int64_t)rmax - w->row > HF_SEEK_ROWS) {
            /* the next row's start, skipped over below */
            if (bd && w->R < bd->thr &&
                hf_band_left(s, f, bd, w->row + 1, (int32_t)w->column, w->column, w->R))
                return 2;
            if (rmax >= L->b1) {
                /* the line's last row lies in the tile: it leaves only if it passes cmax */
                if (L->a1 <= cmax) {
                    /* the row before the last may end on cmax (the last one: hf_band_end) */
                    if (bd) {
                        int64_t c, R;
                        walker_crossing(L, L->b1, w->W, &c, &R);
                        if ((R == 0 || R > bd->right_cut) &&
                            hf_band_right(s, f, bd, L->b1 - 1, (int32_t)(R == 0 ? c - 1 : c), c, R))
                            return 2;
                    }
                    return 1;
                }
            } else {
                int64_t c, R;
                walker_crossing(L, (int64_t)rmax + 1, w->W, &c, &R);
                if (c <= cmax) {
                    if (bd && (R == 0 || R > bd->right_cut) &&
                        hf_band_right(s, f, bd, rmax, (int32_t)(R == 0 ? c - 1 : c), c, R))
                        return 2;
                    walker_seek(w, rmax + 1, (int32_t)c);
                    return 0;
                }
            }
            /* through the tile's major face: column cmax + 1, in the row it enters it; the
             * row before that one may end on cmax */
            walker_seek(w, walker_row_of_column(w, cmax + 1), cmax + 1);
            if (bd && (w->R_in == 0 || w->R_in > bd->right_cut) &&
                hf_band_right(s, f, bd, w->row - 1, w->R_in == 0 ? w->first - 1 : w->first,
                              w->first, w->R_in))
                return 2;
            return 0;
        }
        {
            const int32_t row = w->row, last = w->last;
            const int64_t column = w->column, R = w->R;
            walker_next_row(w);
            if (bd && (R == 0 || R > bd->right_cut) &&
                hf_band_right(s, f, bd, row, last, column, R))
                return 2;
            if (w->row > rmax || w->first > cmax) return 0;
            if (bd && w->R_in < bd->thr &&
                hf_band_left(s, f, bd, w->row, w->first, w->first, w->R_in))
                return 2;
        }
    }
}

int hf_runs_maxmip_hit(hf_batch *b, hf_sink *s, const hf_mipmap *m) {
    hf_line L;
    hf_frame f;
    hf_cull cull;
    run_walker w;
    hf_band bd;
    const hf_band *band;
    hf_hit *h = s->hit;
    int status, level, floor_level;
    int64_t guard;
    const int top = m->n_levels - 1;
    const int descending = h->dz < 0;
    const int32_t fx = h->dx > 0, fy = h->dy > 0;
    const int has_x = h->dx != 0, has_y = h->dy != 0;
    const double inf = (double)INFINITY;
    double t = h->t0;
    if (!hf_exact_begin(b, 0, s, HF_MODE_HIT, 0, 1, &L, &f, &cull, &status)) return status;
    hf_band_init(&bd, h, &L);
    if (bd.on && (bd.wide || bd.full || L.slope_minor == 0)) {
        /* off the lattice with a band wider than a cell (or a straight line): the run walk
         * over the band, unskipped (walk.h) */
        status = runs_band(s, &cull, &L, &f, &bd);
        hf_cull_end(&cull, s, HF_MODE_HIT);
        return status;
    }
    band = bd.on ? &bd : NULL;
    if (band && hf_band_start(s, &f, &L, band)) {
        hf_cull_end(&cull, s, HF_MODE_HIT);
        return HF_OK;
    }
    floor_level = m->floor_level < top ? m->floor_level : top;
    w.L = &L;
    w.row = L.b0;
    w.first = w.pos = L.a0;
    w.W = L.slope_minor * HF_ONE;
    w.column = w.R = 0;
    w.R_in = INT64_MAX;
    w.short_length = w.rem = 0;
    if (L.slope_minor != 0) {
        w.short_length = L.slope_major / L.slope_minor;
        w.rem = (L.slope_major % L.slope_minor) * HF_ONE;
        walker_crossing(&L, (int64_t)L.b0 + 1, w.W, &w.column, &w.R);
    }
    walker_set_last(&w);
    level = floor_level + 1 < top ? floor_level + 1 : top;
    for (guard = 0; guard <= (int64_t)(top + 2) * (2 * ((int64_t)b->nx + b->ny) + 4); ++guard) {
        /* the walker's cell in grid indices, and its tile at this level */
        const int32_t major = f.base_major + f.sign_major * w.pos;
        const int32_t minor = f.base_minor + f.sign_minor * w.row;
        const int32_t i = f.swap ? minor : major, j = f.swap ? major : minor;
        const int32_t tile_i = i >> level, tile_j = j >> level;
        const double t_exit_x =
            has_x ? hf_face_t(hf_tile_face(tile_i, level, fx), h->ox, h->inv_dx) : inf;
        const double t_exit_y =
            has_y ? hf_face_t(hf_tile_face(tile_j, level, fy), h->oy, h->inv_dy) : inf;
        const double t_exit = t_exit_x < t_exit_y ? (t_exit_x < h->t1 ? t_exit_x : h->t1)
                                                  : (t_exit_y < h->t1 ? t_exit_y : h->t1);
        const float tile_max = m->levels[level][(int64_t)tile_j * m->cols[level] + tile_i];
        int32_t cmax, rmax;
        if (!(hf_tile_zlow(h->oz_cull, h->dz, descending, t, t_exit) > (double)tile_max) &&
            level > floor_level) {
            --level;
            continue;
        }
        {
            /* the tile's last column and row in the reduced frame */
            const int64_t size = (int64_t)1 << level;
            const int64_t lo_major = (int64_t)(major >> level) << level;
            const int64_t lo_minor = (int64_t)(minor >> level) << level;
            cmax = (int32_t)(f.sign_major > 0
                                 ? (lo_major + size <= L.n_major ? lo_major + size : L.n_major) -
                                       1 - f.base_major
                                 : f.base_major - lo_major);
            rmax = (int32_t)(f.sign_minor > 0
                                 ? (lo_minor + size <= L.n_minor ? lo_minor + size : L.n_minor) -
                                       1 - f.base_minor
                                 : f.base_minor - lo_minor);
        }
        if (hf_tile_zlow(h->oz_cull, h->dz, descending, t, t_exit) > (double)tile_max) {
            int left;
            h->tiles_skipped += 1;
            /* a row starting here: its band cells left of it may lie outside the tile */
            if (band && w.pos == w.first && w.R_in < band->thr &&
                hf_band_left(s, &f, band, w.row, w.first, w.first, w.R_in)) {
                hf_cull_end(&cull, s, HF_MODE_HIT);
                return HF_OK;
            }
            left = walker_leave(&w, cmax, rmax, s, &f, band);
            if (left == 2) {
                hf_cull_end(&cull, s, HF_MODE_HIT);
                return HF_OK;
            }
            if (left) break;
            if (level < top) ++level;
        } else {
            /* the floor tile: its segment of each run */
            int ended = 0;
            for (;;) {
                const int32_t seg_last = w.last < cmax ? w.last : cmax;
                if ((band && w.pos == w.first && w.R_in < band->thr &&
                     hf_band_left(s, &f, band, w.row, w.first, w.first, w.R_in)) ||
                    hf_visit_reduced_run(s, HF_MODE_HIT, &cull, &f, w.row, w.pos, seg_last) ||
                    (band && seg_last == w.last && w.row < L.b1 &&
                     (w.R == 0 || w.R > band->right_cut) &&
                     hf_band_right(s, &f, band, w.row, w.last, w.column, w.R))) {
                    hf_cull_end(&cull, s, HF_MODE_HIT);
                    return HF_OK;
                }
                if (w.last > cmax) {
                    w.pos = cmax + 1;
                    break;
                }
                if (w.row >= L.b1) {
                    ended = 1;
                    break;
                }
                walker_next_row(&w);
                if (w.row > rmax || w.first > cmax) break;
            }
            if (ended) break;
            level = floor_level + 1 < top ? floor_level + 1 : top;
        }
        t = t_exit > t ? t_exit : t;
    }
    if (band) hf_band_end(s, &f, &L, band);
    hf_cull_end(&cull, s, HF_MODE_HIT);
    return HF_OK;
}

/* ---- runs_periodic: replay the run pattern of a rational slope --------------------------
 * For a slope p/q in lowest terms the fractional crossing position advances by
 * (q mod p)/p per run, so its residue a = floor(R / 2^16) in [0, p) walks the cycle
 * a -> (a + q mod p) mod p and the run lengths repeat every p runs (q cells). The pattern
 * holds the lengths from residue 0; a ray's phase is the position of its first residue,
 * position = a (q mod p)^-1 mod p. The sub-lattice offset delta = R mod 2^16 is constant
 * along the ray; a vertex crossing is residue 0 with delta 0. */
static int64_t inverse_mod(int64_t value, int64_t modulus) {
    /* extended Euclid; value and modulus are coprime */
    int64_t r0 = modulus, r1 = value % modulus, s0 = 0, s1 = 1;
    if (modulus == 1) return 0;
    while (r1 != 0) {
        const int64_t k = r0 / r1, r2 = r0 - k * r1, s2 = s0 - k * s1;
        r0 = r1;
        r1 = r2;
        s0 = s1;
        s1 = s2;
    }
    return s0 < 0 ? s0 + modulus : s0;
}

static void build_pattern(hf_pattern *pattern, int64_t p, int64_t q) {
    const int64_t q_mod_p = q % p, short_length = q / p;
    int64_t k, residue = 0;
    for (k = 0; k < p; ++k) {
        pattern->lengths[k] = (int32_t)(short_length + (residue + q_mod_p >= p ? 1 : 0));
        residue += q_mod_p;
        if (residue >= p) residue -= p;
    }
    pattern->p = p;
    pattern->q = q;
    pattern->position_step = inverse_mod(q_mod_p, p);
}

/* The pattern loop from the first crossing (column, remainder R0); `band`: widened runs
 * for a first hit off the lattice (walk.h), the remainder R then carried per run. */
HF_INLINE int periodic_loop(hf_sink *s, const int mode, hf_cull *cull, const hf_line *L,
                            const hf_frame *f, const int32_t *lengths, int64_t p, int64_t column,
                            int64_t delta, int64_t position, int64_t R0, const hf_band *bd,
                            const int band) {
    int32_t row, first, last;
    int64_t R = R0, R_in = INT64_MAX;
    const int64_t W = p * HF_ONE, rem = (L->slope_major % p) * HF_ONE;
    first = L->a0;
    if (band && hf_band_start(s, f, L, bd)) return HF_OK;
    for (row = L->b0; row < L->b1; ++row) {
        last = (int32_t)((position == 0 && delta == 0) ? column - 1 : column);
        if (band && R_in < bd->thr && hf_band_left(s, f, bd, row, first, first, R_in)) return HF_OK;
        if (hf_visit_reduced_run(s, mode, cull, f, row, first, last)) return HF_OK;
        if (band) {
            if ((R == 0 || R > bd->right_cut) && hf_band_right(s, f, bd, row, last, column, R))
                return HF_OK;
            R_in = R;
            R += rem;
            if (R >= W) R -= W;
        }
        first = (int32_t)column;
        column += lengths[position];
        if (++position == p) position = 0;
    }
    if (first > L->a1) return HF_ERR_INTERNAL;
    if (band && R_in < bd->thr && hf_band_left(s, f, bd, L->b1, first, first, R_in)) return HF_OK;
    if (hf_visit_reduced_run(s, mode, cull, f, L->b1, first, L->a1)) return HF_OK;
    if (band) hf_band_end(s, f, L, bd);
    return HF_OK;
}

HF_INLINE int walk_runs_periodic(hf_batch *b, int64_t ray, hf_sink *s, const int mode, void *ctx) {
    hf_pattern *pattern = (hf_pattern *)ctx;
    hf_line L;
    hf_frame f;
    int64_t p, column, delta, position, R0;
    hf_cull cull;
    hf_band bd;
    int status;
    if (!hf_exact_begin(b, ray, s, mode, b->max_denominator, 1, &L, &f, &cull, &status))
        return status;
    bd.on = 0;
    if (mode == HF_MODE_HIT) hf_band_init(&bd, s->hit, &L);
    if (L.slope_minor == 0) {
        if (mode == HF_MODE_HIT && bd.on)
            hf_band_straight(s, &f, &bd);
        else
            hf_visit_reduced_run(s, mode, &cull, &f, L.b0, L.a0, L.a1);
        hf_cull_end(&cull, s, mode);
        return HF_OK;
    }
    p = L.slope_minor;
    if (p > b->max_denominator) return HF_ERR_CAPACITY;
    /* A pattern costs p steps to build and pays back one step per run; a ray with fewer
     * runs than that, on a slope whose pattern is not already built, takes the plain
     * recurrence on the same rational line: the same runs, exactly. */
    if ((pattern->p != p || pattern->q != L.slope_major) && (int64_t)L.b1 - L.b0 < p) {
        const int done = mode == HF_MODE_HIT && bd.on
                             ? runs_recurrence(s, mode, &cull, &L, &f, &bd, 1)
                             : runs_recurrence(s, mode, &cull, &L, &f, NULL, 0);
        hf_cull_end(&cull, s, mode);
        return done;
    }
    /* parallel rays share one pattern; a new slope builds a new one */
    if (pattern->p != p || pattern->q != L.slope_major) build_pattern(pattern, p, L.slope_major);
    {
        /* start clipping gives the phase: the first crossing, exactly */
        const hf_i128 W = (hf_i128)p * HF_ONE;
        const hf_i128 N =
            (hf_i128)L.o_major * p + ((hf_i128)(L.b0 + 1) * HF_ONE - L.o_minor) * L.slope_major;
        const hf_i128 c = hf_floor_div(N, W);
        const int64_t R = (int64_t)(N - c * W);
        column = (int64_t)c;
        delta = R % HF_ONE;
        R0 = R;
        /* the residue R / 2^16 and position_step are both below p <= slope_major < 2^31
         * (the rounded direction's scale), so their product is below 2^62: a 64-bit
         * modulo, not a 128-bit one, per ray */
        HF_ASSERT(R / HF_ONE < p && pattern->position_step < p && p < ((int64_t)1 << 31),
                  "R=%lld p=%lld step=%lld", (long long)R, (long long)p,
                  (long long)pattern->position_step);
        position = (R / HF_ONE) * pattern->position_step % p;
    }
    status = mode == HF_MODE_HIT && bd.on ? periodic_loop(s, mode, &cull, &L, &f, pattern->lengths,
                                                          p, column, delta, position, R0, &bd, 1)
                                          : periodic_loop(s, mode, &cull, &L, &f, pattern->lengths,
                                                          p, column, delta, position, R0, NULL, 0);
    hf_cull_end(&cull, s, mode);
    return status;
}

HF_DEFINE_BATCH(hf_batch_runs_periodic, walk_runs_periodic)

/* ---- runs_f64: the same recurrence in float64 -----------------------------------------
 * The paper's float formulation: clip in float64, then carry the crossing column and its
 * fractional part `frac` in doubles. Not exact: rounding can move a run boundary, and the
 * accuracy study reports how often. Loops are bounded by the clipped cell range, so a
 * rounding error can shorten or lengthen a run but never run away or write out of bounds. */
HF_INLINE int walk_runs_f64(hf_batch *b, int64_t ray, hf_sink *s, const int mode, void *ctx) {
    const double *o = b->origins + 2 * ray, *d = b->directions + 2 * ray;
    const int swap = fabs(d[1]) > fabs(d[0]);
    const int32_t n_major = swap ? b->ny : b->nx, n_minor = swap ? b->nx : b->ny;
    const int mirror_major = d[swap] < 0, mirror_minor = d[1 - swap] < 0;
    const double A = fabs(d[swap]), B = fabs(d[1 - swap]);
    const double o_major = mirror_major ? n_major - o[swap] : o[swap];
    const double o_minor = mirror_minor ? n_minor - o[1 - swap] : o[1 - swap];
    double t0 = hf_tmin(b, ray), t1 = hf_tmax(b, ray);
    double a_start, b_start, a_end, b_end, slope_inverse, frac, crossing, step_frac;
    int32_t row, first, last, row0, row1, col0, col1;
    int64_t column, step_whole;
    hf_frame f;
    hf_cull cull;
    int status = hf_ray_begin(b, ray, s, mode, !swap);
    (void)ctx;
    if (status != HF_OK) return status;
    if (A == 0.0) {
        /* vertical: the cell under the origin */
        if (!(t0 < t1) || !(o[0] >= 0 && o[0] < b->nx && o[1] >= 0 && o[1] < b->ny)) return HF_OK;
        hf_emit_run(s, mode, (int32_t)floor(o[1]), (int32_t)floor(o[0]), (int32_t)floor(o[0]));
        return HF_OK;
    }
    /* slab clipping in float64 */
    t0 = fmax(t0, (0.0 - o_major) / A);
    t1 = fmin(t1, (n_major - o_major) / A);
    if (B > 0.0) {
        t0 = fmax(t0, (0.0 - o_minor) / B);
        t1 = fmin(t1, (n_minor - o_minor) / B);
    } else if (!(o_minor >= 0.0 && o_minor < n_minor)) {
        return HF_OK;
    }
    if (!(t0 < t1)) return HF_OK;
    a_start = floor(o_major + t0 * A);
    b_start = floor(o_minor + t0 * B);
    a_end = ceil(o_major + t1 * A) - 1.0;
    b_end = B > 0.0 ? ceil(o_minor + t1 * B) - 1.0 : b_start;
    col0 = (int32_t)fmin(fmax(a_start, 0.0), n_major - 1.0);
    row0 = (int32_t)fmin(fmax(b_start, 0.0), n_minor - 1.0);
    col1 = (int32_t)fmin(fmax(a_end, (double)col0), n_major - 1.0);
    row1 = (int32_t)fmin(fmax(b_end, (double)row0), n_minor - 1.0);
    f.base_major = mirror_major ? n_major - 1 : 0;
    f.sign_major = mirror_major ? -1 : 1;
    f.base_minor = mirror_minor ? n_minor - 1 : 0;
    f.sign_minor = mirror_minor ? -1 : 1;
    f.swap = swap;
    hf_cull_begin_reduced(&cull, s, mode, &f, col0, row0, 1);
    if (B == 0.0 || row0 == row1) {
        hf_visit_reduced_run(s, mode, &cull, &f, row0, col0, col1);
        hf_cull_end(&cull, s, mode);
        return HF_OK;
    }
    /* a nearly flat slope: clamp before converting to integers (no overflow UB); any
     * value past 2^40 cells lies beyond every grid */
    slope_inverse = fmin(A / B, 1099511627776.0);
    step_whole = (int64_t)floor(slope_inverse);
    step_frac = slope_inverse - (double)step_whole;
    crossing = o_major + (row0 + 1.0 - o_minor) * slope_inverse;
    crossing = fmin(fmax(crossing, -1099511627776.0), 1099511627776.0);
    column = (int64_t)floor(crossing);
    frac = crossing - (double)column;
    first = col0;
    for (row = row0; row < row1; ++row) {
        last = (int32_t)(frac == 0.0 ? column - 1 : column);
        if (last > col1) last = col1;
        if (last < first) last = first;
        if (hf_visit_reduced_run(s, mode, &cull, &f, row, first, last)) {
            hf_cull_end(&cull, s, mode);
            return HF_OK;
        }
        first = column > col1 ? col1 : (int32_t)column;
        if (first < last) first = last;
        column += step_whole;
        frac += step_frac;
        if (frac >= 1.0) {
            frac -= 1.0;
            column += 1;
        }
    }
    hf_visit_reduced_run(s, mode, &cull, &f, row1, first, col1 < first ? first : col1);
    hf_cull_end(&cull, s, mode);
    return HF_OK;
}

HF_DEFINE_BATCH(hf_batch_runs_f64, walk_runs_f64)
