/* Exact signs for the first-hit decisions that float64 cannot make: whether the ray is at,
 * above or below a cell's surface at a point whose parameter is not a float (a grid-line
 * crossing t = (k - o) / d, or the triangles' diagonal crossing u = v). Integer rays meet
 * such ties often: a touch at t = 2/3 is a hit that rounding can turn into a miss.
 *
 * Numbers are floating-point expansions (Shewchuk, "Adaptive precision floating-point
 * arithmetic and fast robust geometric predicates", Discrete Comput. Geom. 18, 1997,
 * sections 2.3-2.6): a sum of doubles, nonoverlapping and in order of increasing
 * magnitude, whose sign is the sign of its largest component. Sums use two-sum, products
 * the fused multiply-add's exact error (fma(a, b, -a b)). The inputs are kept within
 * 2^-250 .. 2^250 in magnitude, so no product of three of them overflows or underflows and
 * every operation is exact; hf_ex_in_range checks it (the caller falls back to float64
 * outside). These are cold paths: clarity over speed. */
#ifndef HFTRACE_EXACT_H
#define HFTRACE_EXACT_H

#include <math.h>

/* Room for the longest expansion the surface tests build: at most 144 components (a gap's
 * sign, hf_exact_gap_sign in exact_cell.h; an event comparison needs 16). An operation
 * that would pass it fails instead, which these bounds never let happen. */
#define HF_EX_CAP 192

typedef struct {
    int n;
    double c[HF_EX_CAP];
} hf_ex;

/* a + b = s + e exactly (Knuth's two-sum). */
static inline void hf_two_sum(double a, double b, double *s, double *e) {
    const double sum = a + b, bv = sum - a, av = sum - bv;
    *s = sum;
    *e = (a - av) + (b - bv);
}

static inline void hf_ex_set(hf_ex *e, double a) {
    e->n = a != 0;
    e->c[0] = a;
}

/* e += b (Shewchuk's Grow-Expansion, zero components dropped). Returns 0 when full. */
static inline int hf_ex_grow(hf_ex *e, double b) {
    double q = b;
    int k = 0, m;
    for (m = 0; m < e->n; ++m) {
        double s, err;
        hf_two_sum(q, e->c[m], &s, &err);
        q = s;
        if (err != 0) e->c[k++] = err;
    }
    if (q != 0) {
        if (k >= HF_EX_CAP) return 0;
        e->c[k++] = q;
    }
    e->n = k;
    return 1;
}

/* e += s * f, s = +-1. */
static inline int hf_ex_add(hf_ex *e, const hf_ex *f, double s) {
    int m;
    for (m = 0; m < f->n; ++m)
        if (!hf_ex_grow(e, s * f->c[m])) return 0;
    return 1;
}

/* e += f * b, exactly: each component's product and its rounding error. */
static inline int hf_ex_add_scaled(hf_ex *e, const hf_ex *f, double b) {
    int m;
    for (m = 0; m < f->n; ++m) {
        const double p = f->c[m] * b, err = fma(f->c[m], b, -p);
        if (!hf_ex_grow(e, err) || !hf_ex_grow(e, p)) return 0;
    }
    return 1;
}

/* e += f * g. */
static inline int hf_ex_add_product(hf_ex *e, const hf_ex *f, const hf_ex *g) {
    int m;
    for (m = 0; m < g->n; ++m)
        if (!hf_ex_add_scaled(e, f, g->c[m])) return 0;
    return 1;
}

/* a - b as an expansion (two components at most). */
static inline void hf_ex_diff(hf_ex *e, double a, double b) {
    hf_ex_set(e, a);
    (void)hf_ex_grow(e, -b);
}

static inline int hf_ex_sign(const hf_ex *e) {
    if (e->n == 0) return 0;
    return e->c[e->n - 1] > 0 ? 1 : -1;
}

/* The expansion's value to within a few units of rounding. */
static inline double hf_ex_estimate(const hf_ex *e) {
    double s = 0;
    int m;
    for (m = 0; m < e->n; ++m) s += e->c[m];
    return s;
}

/* Whether a is 0 or within 2^-250 .. 2^250 in magnitude (see the head of this file). */
static inline int hf_ex_in_range(double a) {
    const double m = fabs(a);
    return a == 0 || (m >= 0x1p-250 && m <= 0x1p250);
}

/* Whether o + t d equals k exactly (in range: the caller's floats; else the float64 test). */
static inline int hf_exact_on_line(double o, double d, double t, double k) {
    hf_ex e;
    const double p = t * d;
    if (!(hf_ex_in_range(o) && hf_ex_in_range(d) && hf_ex_in_range(t) && hf_ex_in_range(k)))
        return o + p == k;
    hf_ex_set(&e, fma(t, d, -p));
    (void)(hf_ex_grow(&e, p) && hf_ex_grow(&e, o) && hf_ex_grow(&e, -k));
    return hf_ex_sign(&e) == 0;
}

#endif
