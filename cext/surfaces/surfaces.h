/* The cell surfaces and their root solvers, in one place for every consumer: the
 * per-cell first-hit tests (cell_test.h), the ray marchers (dispatch/intersect.c), the cone kernels
 * (cone.c) and the terrain products (terrain.c). Surfaces and names: docs/CONVENTIONS.md, "Cell
 * surfaces"; corners h00 = H[j,i], h10 = H[j,i+1], h01 = H[j+1,i], h11 = H[j+1,i+1], local
 * coordinates u = x - i, v = y - j.
 *
 * Two evaluations of a linear piece are kept on purpose, because they round differently
 * and each consumer's outputs are pinned bit for bit: the slope form h00 + su u + sv v
 * (the first-hit tests, exact at the origin corner) and the barycentric form (terrain,
 * exact at every corner and free of cancellation on the edges). */
#ifndef HFTRACE_SURFACES_H
#define HFTRACE_SURFACES_H

#include <math.h>

/* ---- the four surfaces ------------------------------------------------------------------ */

/* flat: the mean of the four corners. */
static inline double hf_flat_height(double h00, double h10, double h01, double h11) {
    return (h00 + h10 + h01 + h11) / 4.0;
}

/* A plane through the corner (0, 0, h00) with slopes su = ds/du and sv = ds/dv. */
static inline double hf_plane_height(double h00, double su, double sv, double u, double v) {
    return h00 + su * u + sv * v;
}

/* plane3: the plane through h00, h10 and h01. */
static inline void hf_plane3_slopes(double h00, double h10, double h01, double *su, double *sv) {
    *su = h10 - h00;
    *sv = h01 - h00;
}

/* triangles: the lower triangle (u >= v) through h00, h10, h11 and the upper one (u < v)
 * through h00, h01, h11, each as a plane through h00. */
static inline void hf_lower_triangle_slopes(double h00, double h10, double h11, double *su,
                                            double *sv) {
    *su = h10 - h00;
    *sv = h11 - h10;
}

static inline void hf_upper_triangle_slopes(double h00, double h01, double h11, double *su,
                                            double *sv) {
    *su = h11 - h01;
    *sv = h01 - h00;
}

/* bilinear: s = h00 + a u + b v + c u v. */
typedef struct {
    double a, b, c;
} hf_bilinear;

static inline hf_bilinear hf_bilinear_of(double h00, double h10, double h01, double h11) {
    hf_bilinear q;
    q.a = h10 - h00;
    q.b = h01 - h00;
    q.c = h00 - h10 - h01 + h11;
    return q;
}

static inline double hf_bilinear_height(double h00, const hf_bilinear *q, double u, double v) {
    return h00 + q->a * u + q->b * v + q->c * u * v;
}

/* The two-triangle surface in barycentric weights, all >= 0: exact at the corners and no
 * cancellation on the edges (terrain's form; u, v in [0, 1]). */
static inline double hf_triangles_barycentric(double h00, double h10, double h01, double h11,
                                              double u, double v) {
    if (u >= v) return h00 * (1.0 - u) + h10 * (u - v) + h11 * v;
    return h00 * (1.0 - v) + h01 * (v - u) + h11 * u;
}

/* Along one edge or diagonal from height a (w = 0) to b (w = 1), two roundings:
 * hf_lerp_ends is exact at both ends, hf_lerp exact at a and one multiply cheaper. */
static inline double hf_lerp_ends(double a, double b, double w) {
    return a * (1.0 - w) + b * w;
}

static inline double hf_lerp(double a, double b, double w) {
    return a + (b - a) * w;
}

/* ---- root solvers ------------------------------------------------------------------------ */

/* f(t) = z(t) - s(x(t), y(t)) is linear on [ta, tb] with end values fa, fb (fa > 0):
 * the root, kept inside the interval. */
static inline double hf_linear_root(double ta, double tb, double fa, double fb) {
    double t = ta + (tb - ta) * (fa / (fa - fb));
    if (!(t >= ta)) t = ta; /* also catches NaN from a degenerate interval */
    if (t > tb) t = tb;
    return t;
}

/* The smallest tau in [0, len] with a tau^2 + b tau + c <= 0, given c > 0; -1 if none.
 * Robust where the quadratic degenerates to a linear one and near double roots, and a
 * sign change the closed forms lose to rounding (a root an ulp past the end) is found by
 * bisection. */
static inline double hf_quadratic_first(double a, double b, double c, double len) {
    const double scale = fabs(b) * fabs(b) + 4.0 * fabs(a * c);
    /* a root within this of the ends is taken as at the end: relative to len, since tau is
     * in units of the ray's d (an absolute slack spans whole cells once |d| >= 2^32) */
    const double slack = 1e-12 * len;
    double best = -1.0;
    int k;
    if (fabs(a) * len <= 1e-14 * (fabs(b) + fabs(c) / (len > 0 ? len : 1.0))) {
        /* effectively linear: b tau + c */
        if (b < 0) {
            const double t = -c / b;
            if (t <= len + slack) best = t < len ? t : len;
        }
    } else {
        double disc = b * b - 4.0 * a * c, roots[2];
        int n = 0;
        /* a tangent touch: a discriminant lost in rounding counts as a double root */
        if (disc < 0 && disc > -1e-12 * scale) disc = 0;
        if (disc >= 0) {
            /* the stable pair of formulas: no cancellation between b and sqrt(disc) */
            const double q = -0.5 * (b + (b >= 0 ? sqrt(disc) : -sqrt(disc)));
            if (q != 0) roots[n++] = c / q;
            roots[n++] = q / a;
        }
        for (k = 0; k < n; ++k) {
            const double t = roots[k];
            if (t >= -slack && t <= len + slack) {
                const double tc = t < 0 ? 0 : (t > len ? len : t);
                if (best < 0 || tc < best) best = tc;
            }
        }
    }
    if (best < 0 && (a * len + b) * len + c <= 0) {
        /* the end is at or below the surface but no root was found: bisect the change */
        double lo = 0, hi = len;
        for (k = 0; k < 200; ++k) {
            const double mid = 0.5 * (lo + hi);
            if (mid <= lo || mid >= hi) break;
            if ((a * mid + b) * mid + c <= 0)
                hi = mid;
            else
                lo = mid;
        }
        best = hi;
    }
    return best;
}

#endif
