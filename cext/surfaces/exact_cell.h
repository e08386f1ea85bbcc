/* A cell's first-hit test decided in exact arithmetic (surfaces/exact.h): the cold path of
 * the per-cell tests (cell_test.h) for flat, plane3 and triangles, taken when a float gap
 * z - s at one of the cell's event points lies within the ray's rounding window of 0.
 *
 * The event points of a cell's interval are exact rationals P / Q (Q > 0):
 * - its start: the latest of the caller's tmin (when finite) and the cell's entry faces
 *   x = k, t = (k - ox) / dx, and y = k, for the components that are not 0;
 * - its end: the earliest of tmax and the exit faces (a range end exactly on a face is
 *   read as the face: the point belongs to the cell entered there);
 * - the triangles' diagonal crossing u = v, t = ((oy - j) - (ox - i)) / (dx - dy).
 * The walk's own floats ta and tb stand for them in the answer's t. Where the walk's
 * interval starts later than the exact start (a z clip, a conservative start bound), the
 * ray is above every surface there, so the exact start decides alike. A range of one
 * point (a ray that only touches the box, or border_point's test of one point) is the
 * cell's exact start. A float walk's cell whose exact interval is empty (the side cell it
 * passes where the ray crosses a grid vertex at such a parameter) is not visited.
 *
 * On a linear piece s = A0 + Au u + Av v the gap is G0 + t G1 with G0 = oz - A0 - Au (ox - i)
 * - Av (oy - j) and G1 = dz - Au dx - Av dy, so Q (z - s) at P / Q is Q G0 + P G1: its sign
 * is exact. The decision then follows docs/CONVENTIONS.md as the rational reference does
 * (algos/exact_hits.py): a gap <= 0 at the start is a hit there; a gap < 0 at a
 * piece's end puts the hit at the piece's root (-G0 / G1, rounded, kept within the piece);
 * a gap of exactly 0 at a piece's end is a hit there, except at an exit into the grid: there
 * flat and plane3 leave the point to the cell entered, and on triangles (continuous) the
 * cell entered holds the touch, which is reported in it. The root's t is the hot path's
 * own float64 root wherever its gaps have the exact signs, so a cell both decide alike
 * keeps its t bit for bit (tests/first_hits/test_hit_pin.py). Bilinear cells (quadratic)
 * stay with float64. */
#ifndef HFTRACE_EXACT_CELL_H
#define HFTRACE_EXACT_CELL_H

#include <stdint.h>
#include "surfaces/exact.h"
#include "surfaces/surfaces.h"

/* What the cold path reads: the ray, its range, the grid and the cell. */
typedef struct {
    double ox, oy, oz, dx, dy, dz, t0, t1, tmin, tmax;
    int32_t cols, rows; /* grid points */
    int surface;        /* enum hf_surface: 0 flat, 1 plane3, 2 triangles */
    int32_t i, j;
    double h00, h10, h01, h11;
    double ta, tb, t_split; /* the caller's floats; t_split = tb when it found no split */
} hf_exact_cell;

/* Its answer. kind: -1 undecided (an input outside exact.h's range: the caller decides in
 * float64), 0 no hit, 1 a hit at the interval's start (the caller's ta, and its wall), 2 a
 * hit at t inside or at the end of a piece. piece: the plane hit (0 flat or plane3, 1 the
 * lower triangle, 2 the upper); (i, j): the cell that holds the hit. */
typedef struct {
    int kind, piece;
    double t;
    int32_t i, j;
} hf_exact_answer;

/* An event P / Q with Q > 0, and its float value. */
typedef struct {
    hf_ex p, q;
    double t;
} hf_event;

/* a = b * sign, c = d * sign over every component (an expansion's negation is exact). */
static inline void hf_ex_negate(hf_ex *e) {
    int m;
    for (m = 0; m < e->n; ++m) e->c[m] = -e->c[m];
}

static inline void hf_event_float(hf_event *e, double t) {
    hf_ex_set(&e->p, t);
    hf_ex_set(&e->q, 1.0);
    e->t = t;
}

/* the grid line x = k (axis 0) or y = k (axis 1) */
static inline void hf_event_face(hf_event *e, const hf_exact_cell *c, int axis, double k,
                                 double t) {
    const double o = axis == 0 ? c->ox : c->oy, d = axis == 0 ? c->dx : c->dy;
    hf_ex_diff(&e->p, k, o);
    hf_ex_set(&e->q, d);
    if (d < 0) {
        hf_ex_negate(&e->p);
        hf_ex_negate(&e->q);
    }
    e->t = t;
}

/* sign(a - b) of two events */
static inline int hf_event_compare(const hf_event *a, const hf_event *b) {
    hf_ex s;
    s.n = 0;
    if (!hf_ex_add_product(&s, &a->p, &b->q)) return 0;
    {
        hf_ex t;
        t.n = 0;
        if (!hf_ex_add_product(&t, &b->p, &a->q)) return 0;
        if (!hf_ex_add(&s, &t, -1.0)) return 0;
    }
    return hf_ex_sign(&s);
}

/* The interval's start (last = 0) or end (last = 1): the latest (earliest) of the caller's
 * tmin (tmax), when finite, and the cell's entry (exit) faces the ray crosses; the float t
 * stands for it. *faces: how many faces are at that event (0: the range's end; 2: a
 * vertex); *axis: one of them. */
static inline void hf_event_bound(hf_event *e, const hf_exact_cell *c, double t, int last,
                                  int *faces, int *axis) {
    const double end = last ? c->tmax : c->tmin;
    int a, n = 0, any = 0;
    *axis = -1;
    if (end > -(double)INFINITY && end < (double)INFINITY) {
        hf_event_float(e, end);
        any = 1;
    }
    for (a = 0; a < 2; ++a) {
        const double d = a == 0 ? c->dx : c->dy;
        const int32_t cell = a == 0 ? c->i : c->j;
        hf_event face;
        int s;
        if (d == 0) continue;
        hf_event_face(&face, c, a, (double)cell + ((d > 0) == (last != 0)), t);
        s = any ? hf_event_compare(&face, e) : (last ? -1 : 1);
        if (s == 0 && n > 0) {
            n = 2; /* a vertex */
        } else if (s == 0) {
            n = 1; /* the range's end on a face: read as the face */
            *axis = a;
        } else if ((s > 0) != (last != 0)) {
            *e = face;
            *axis = a;
            n = 1;
        }
        any = 1;
    }
    if (!any) hf_event_float(e, t);
    e->t = t;
    *faces = n;
}

/* G0 and G1 of piece `piece` of the cell (see the head of this file). */
static inline int hf_exact_piece(const hf_exact_cell *c, int piece, hf_ex *g0, hf_ex *g1) {
    hf_ex a0, au, av, u0, v0;
    if (piece == 0 && c->surface == 0) { /* flat: the mean of the corners */
        int m;
        hf_ex_set(&a0, c->h00);
        (void)(hf_ex_grow(&a0, c->h10) && hf_ex_grow(&a0, c->h01) && hf_ex_grow(&a0, c->h11));
        for (m = 0; m < a0.n; ++m) a0.c[m] *= 0.25;
        au.n = av.n = 0;
    } else {
        hf_ex_set(&a0, c->h00);
        if (piece == 0) { /* plane3: through h00, h10, h01 */
            hf_ex_diff(&au, c->h10, c->h00);
            hf_ex_diff(&av, c->h01, c->h00);
        } else if (piece == 1) { /* the lower triangle (u >= v): h00, h10, h11 */
            hf_ex_diff(&au, c->h10, c->h00);
            hf_ex_diff(&av, c->h11, c->h10);
        } else { /* the upper one: h00, h01, h11 */
            hf_ex_diff(&au, c->h11, c->h01);
            hf_ex_diff(&av, c->h01, c->h00);
        }
    }
    hf_ex_diff(&u0, c->ox, (double)c->i);
    hf_ex_diff(&v0, c->oy, (double)c->j);
    /* G0 = oz - A0 - Au u0 - Av v0; G1 = dz - Au dx - Av dy */
    hf_ex_set(g0, c->oz);
    hf_ex_set(g1, c->dz);
    {
        hf_ex t;
        t.n = 0;
        if (!hf_ex_add_product(&t, &au, &u0) || !hf_ex_add_product(&t, &av, &v0)) return 0;
        if (!hf_ex_add(&t, &a0, 1.0) || !hf_ex_add(g0, &t, -1.0)) return 0;
        t.n = 0;
        if (!hf_ex_add_scaled(&t, &au, c->dx) || !hf_ex_add_scaled(&t, &av, c->dy)) return 0;
        if (!hf_ex_add(g1, &t, -1.0)) return 0;
    }
    return 1;
}

/* sign of the gap at event e on the piece with g0, g1 (2: the expansions ran out of room) */
static inline int hf_exact_gap_sign(const hf_event *e, const hf_ex *g0, const hf_ex *g1) {
    hf_ex s;
    s.n = 0;
    if (!hf_ex_add_product(&s, g0, &e->q) || !hf_ex_add_product(&s, g1, &e->p)) return 2;
    return hf_ex_sign(&s);
}

/* The piece of the triangles holding the interval just after event e: lower where
 * u - v > 0 there, or where the ray heads into it (u - v = 0 and dx - dy > 0), or along
 * the diagonal (u = v throughout, which the lower triangle holds). */
static inline int hf_exact_triangle_after(const hf_exact_cell *c, const hf_event *e) {
    hf_ex s, uv, w;
    int sign;
    hf_ex_diff(&uv, c->ox, (double)c->i);
    (void)hf_ex_grow(&uv, -c->oy);
    (void)hf_ex_grow(&uv, (double)c->j);
    hf_ex_diff(&w, c->dx, c->dy);
    s.n = 0;
    /* Q (u - v) at P / Q = Q (u0 - v0) + P (dx - dy) */
    if (!hf_ex_add_product(&s, &uv, &e->q) || !hf_ex_add_product(&s, &w, &e->p)) return 1;
    sign = hf_ex_sign(&s);
    if (sign == 0) sign = hf_ex_sign(&w);
    return sign >= 0 ? 1 : 2;
}

static inline int hf_exact_inputs_in_range(const hf_exact_cell *c, double t_float) {
    return hf_ex_in_range(c->ox) && hf_ex_in_range(c->oy) && hf_ex_in_range(c->oz) &&
           hf_ex_in_range(c->dx) && hf_ex_in_range(c->dy) && hf_ex_in_range(c->dz) &&
           hf_ex_in_range(t_float) && (isinf(c->tmin) || hf_ex_in_range(c->tmin)) &&
           (isinf(c->tmax) || hf_ex_in_range(c->tmax));
}

/* The float64 gap at t on a piece, by the very expressions of the hot path (cell_test.h),
 * so that a decision both make alike gives the same t bit for bit. */
static inline double hf_exact_float_gap(const hf_exact_cell *c, int piece, double t) {
    const double z = c->oz + t * c->dz;
    double su, sv;
    if (piece == 0 && c->surface == 0) return z - hf_flat_height(c->h00, c->h10, c->h01, c->h11);
    if (piece == 0)
        hf_plane3_slopes(c->h00, c->h10, c->h01, &su, &sv);
    else if (piece == 1)
        hf_lower_triangle_slopes(c->h00, c->h10, c->h11, &su, &sv);
    else
        hf_upper_triangle_slopes(c->h00, c->h01, c->h11, &su, &sv);
    return z - hf_plane_height(c->h00, su, sv, c->ox + t * c->dx - c->i, c->oy + t * c->dy - c->j);
}

/* Where the gap of a piece from event x to event y, positive at x, reaches 0 (at y when
 * touch): the float64 root of the hot path where its gaps have the exact signs, else the
 * exact root -G0 / G1 rounded (or y itself for a touch), kept within [x, y]. */
static inline double hf_exact_root(const hf_exact_cell *c, int piece, const hf_event *x,
                                   const hf_event *y, const hf_ex *g0, const hf_ex *g1, int touch) {
    const double fx = hf_exact_float_gap(c, piece, x->t), fy = hf_exact_float_gap(c, piece, y->t);
    double t;
    if (fx > 0 && (touch ? fy <= 0 : fy < 0)) return hf_linear_root(x->t, y->t, fx, fy);
    t = touch ? y->t : -hf_ex_estimate(g0) / hf_ex_estimate(g1);
    if (!(t >= x->t)) t = x->t;
    if (t > y->t) t = y->t;
    return t;
}

/* Whether the cell is visited: its exact interval [start, end) is not empty (1), it is
 * (0), or the inputs are out of range (-1). A range of one point (t0 = t1) visits its cell. */
static inline int hf_exact_visits(const hf_exact_cell *c) {
    hf_event a, b;
    int faces, axis;
    if (!(c->t0 < c->t1)) return 1;
    if (!hf_exact_inputs_in_range(c, c->ta) || !hf_ex_in_range(c->tb)) return -1;
    hf_event_bound(&a, c, c->ta, 0, &faces, &axis);
    hf_event_bound(&b, c, c->tb, 1, &faces, &axis);
    return hf_event_compare(&a, &b) < 0;
}

/* The cell's test in exact arithmetic (see the head of this file). */
static inline hf_exact_answer hf_exact_cell_decide(const hf_exact_cell *c) {
    hf_exact_answer r;
    hf_event a, b, s;
    const hf_event *ends[3];
    int faces_a, faces_b, axis_a, axis_b, n_pieces = 1, planes[2] = {0, 0}, p;
    r.kind = -1;
    r.piece = 0;
    r.t = c->ta;
    r.i = c->i;
    r.j = c->j;
    if (!hf_exact_inputs_in_range(c, c->ta) || !hf_ex_in_range(c->tb)) return r;
    hf_event_bound(&a, c, c->ta, 0, &faces_a, &axis_a);
    hf_event_bound(&b, c, c->tb, 1, &faces_b, &axis_b);
    if (!(c->t0 < c->t1)) {
        /* a range of one point (a ray that only touches the box, or border_point's test of
         * the point where a cell is entered): the cell's start */
        b = a;
        b.t = c->tb;
        faces_b = faces_a;
    } else if (hf_event_compare(&a, &b) >= 0) { /* not visited: a vertex's side */
        r.kind = 0;
        return r;
    }
    ends[0] = &a;
    ends[1] = &b;
    if (c->surface == 2) { /* triangles: split where the ray crosses u = v inside */
        planes[0] = hf_exact_triangle_after(c, &a);
        if (c->dx != c->dy) {
            hf_ex_diff(&s.p, c->oy, (double)c->j);
            (void)(hf_ex_grow(&s.p, -c->ox) && hf_ex_grow(&s.p, (double)c->i));
            hf_ex_diff(&s.q, c->dx, c->dy);
            if (hf_ex_sign(&s.q) < 0) {
                hf_ex_negate(&s.p);
                hf_ex_negate(&s.q);
            }
            s.t = c->t_split < c->tb ? c->t_split : hf_ex_estimate(&s.p) / hf_ex_estimate(&s.q);
            if (hf_event_compare(&s, &a) > 0 && hf_event_compare(&s, &b) < 0) {
                if (!(s.t >= c->ta)) s.t = c->ta;
                if (s.t > c->tb) s.t = c->tb;
                n_pieces = 2;
                ends[1] = &s;
                ends[2] = &b;
                planes[1] = hf_exact_triangle_after(c, &s);
            }
        }
    }
    for (p = 0; p < n_pieces; ++p) {
        const hf_event *x = ends[p], *y = ends[p + 1];
        hf_ex g0, g1;
        int sx, sy;
        if (!hf_exact_piece(c, planes[p], &g0, &g1)) return r;
        sx = hf_exact_gap_sign(x, &g0, &g1);
        if (sx == 2) return r;
        r.piece = planes[p];
        if (sx <= 0) { /* at or below where the piece starts */
            r.kind = p == 0 ? 1 : 2;
            r.t = x->t;
            return r;
        }
        sy = hf_exact_gap_sign(y, &g0, &g1);
        if (sy == 2) return r;
        if (sy < 0) { /* crosses inside */
            r.kind = 2;
            r.t = hf_exact_root(c, planes[p], x, y, &g0, &g1, 0);
            return r;
        }
        if (sy == 0) {
            int32_t ni = c->i, nj = c->j;
            r.t = hf_exact_root(c, planes[p], x, y, &g0, &g1, 1);
            if (p + 1 < n_pieces || faces_b == 0) { /* the split, or the range's end */
                r.kind = 2;
                return r;
            }
            /* an exit face: the cell entered there, if the grid goes on */
            if (faces_b == 2 || axis_b == 0) ni += c->dx > 0 ? 1 : -1;
            if (faces_b == 2 || axis_b == 1) nj += c->dy > 0 ? 1 : -1;
            if (ni < 0 || ni > c->cols - 2 || nj < 0 || nj > c->rows - 2) {
                r.kind = 2; /* the box's far side is closed */
                return r;
            }
            if (c->surface != 2) break; /* flat, plane3: the cell entered decides */
            r.kind = 2;                 /* triangles: the same point, the cell entered's */
            r.piece = 3;
            r.i = ni;
            r.j = nj;
            return r;
        }
    }
    r.kind = 0;
    return r;
}

#endif
