/* The exact line: rounding onto the lattice, octant reduction, and exact clipping of
 * [tmin, tmax) to the grid. Shared by midpoint, runs and runs_periodic.
 *
 * The lattice (documented in algos/lattice.py, which mirrors it):
 *   origin:    O = round_half_even(o * 2^16), so o is rounded to a multiple of 2^-16 cell;
 *   direction: d is scaled by 2^s so that max(|dx|, |dy|) * 2^s lies in [2^30, 2^31),
 *              then D = round_half_even(d * 2^s). The rounded ray is (O 2^-16, D 2^-s).
 * Scaling d by a power of two changes no cell; tmin/tmax keep their meaning because the
 * rounded direction is D 2^-s, in the caller's units.
 * Every comparison against tmin/tmax below is exact: t is split into m 2^e with integer m
 * and compared in 128-bit integers. */
#include <math.h>
#include "walks/walk.h"

/* ---- Exact floating-point helpers ------------------------------------------------------
 * Without SSE4.1 the libm calls nearbyint, frexp and ldexp are real function calls, and a
 * ray's setup would make about ten of them; these do the same exactly, inline. */
#include <string.h>

/* frexp's exponent: x = m 2^e with |m| in [0.5, 1); x finite and non-zero */
static int exponent_of(double x) {
    uint64_t bits;
    int biased;
    memcpy(&bits, &x, sizeof bits);
    biased = (int)((bits >> 52) & 0x7FF);
    if (biased == 0) { /* subnormal: rare, let libm handle it */
        int e;
        (void)frexp(x, &e);
        return e;
    }
    return biased - 1022;
}

/* 2^k as a double, for -1022 <= k <= 1023 */
static double pow2(int k) {
    const uint64_t bits = (uint64_t)(k + 1023) << 52;
    double x;
    memcpy(&x, &bits, sizeof x);
    return x;
}

/* x * 2^k, exact whenever the result is a normal number (as ldexp) */
static double scale2(double x, int k) {
    while (k > 1000) {
        x *= pow2(1000);
        k -= 1000;
    }
    while (k < -1000) {
        x *= pow2(-1000);
        k += 1000;
    }
    return x * pow2(k);
}

/* round half to even (as nearbyint in the default rounding mode) for |x| < 2^51: adding
 * and subtracting 1.5 2^52 leaves exactly the integer the hardware rounds to */
static double round_even(double x) {
    const double magic = 6755399441055744.0; /* 1.5 2^52 */
    volatile double y = x + magic;           /* volatile: keep the two roundings apart */
    return fabs(x) < 2251799813685248.0 ? y - magic : nearbyint(x);
}

/* ---- Rounding onto the lattice -------------------------------------------------------- */
static int direction_scale(double dx, double dy) {
    /* max in [2^(e-1), 2^e) */
    return HF_DIR_BITS - exponent_of(fmax(fabs(dx), fabs(dy)));
}

void hf_quantize_ray(const double origin[2], const double direction[2], double origin_out[2],
                     double direction_out[2]) {
    int k, scale = 0;
    const int vertical = direction[0] == 0.0 && direction[1] == 0.0;
    if (!vertical) scale = direction_scale(direction[0], direction[1]);
    for (k = 0; k < 2; ++k) {
        origin_out[k] = round_even(origin[k] * (double)HF_ONE) / (double)HF_ONE;
        direction_out[k] = vertical ? 0.0 : scale2(round_even(scale2(direction[k], scale)), -scale);
        /* -0.0 is the same direction as 0.0 */
        if (direction_out[k] == 0.0) direction_out[k] = 0.0;
    }
}

/* ---- Exact parameters ------------------------------------------------------------------
 * tau is the ray parameter in the lattice frame, tau = t * 2^(16 - s), so that
 * position = O + tau * D. A finite tau is held as mant * 2^expo exactly. Any |tau| >= 2^21
 * lies beyond the box (|O| <= 2^46 + 2^40 and |D_major| >= 2^30), so it is "huge": it
 * behaves as +-infinity for clipping. */
typedef struct {
    int huge;     /* 0: finite, +1: +inf or beyond the box, -1: -inf or before it */
    int64_t mant; /* |mant| < 2^53 */
    int expo;     /* < -31 whenever huge == 0 and mant != 0 */
} hf_param;

static hf_param param_from_t(double t, int shift) {
    hf_param p = {0, 0, 0};
    int exponent;
    if (t == 0.0) return p;
    if (isinf(t)) {
        p.huge = t > 0 ? 1 : -1;
        return p;
    }
    exponent = exponent_of(t);                  /* exact, subnormals included */
    p.mant = (int64_t)scale2(t, 53 - exponent); /* |mant| in [2^52, 2^53) */
    p.expo = exponent - 53 + shift;
    if (p.expo >= -31) p.huge = t > 0 ? 1 : -1; /* |tau| >= 2^52 2^-31 = 2^21 */
    return p;
}

/* max k with base + tau * coeff >= k * den (strict = 0) or > k * den (strict = 1). */
static int64_t lattice_floor(hf_i128 base, hf_i128 coeff, hf_param tau, hf_i128 den, int strict) {
    hf_i128 whole = base; /* integer part of the value */
    int fractional = 0;   /* the value exceeds `whole` by a fraction in (0, 1) */
    if (tau.mant != 0) {
        const hf_i128 product = (hf_i128)tau.mant * coeff; /* < 2^53 * 2^62 */
        const int shift = -tau.expo;                       /* >= 32 */
        hf_i128 floor_part;
        if (shift >= 126) {
            floor_part = product < 0 ? -1 : 0; /* |product| < 2^115: a mere fraction */
            fractional = product != 0;
        } else {
            const hf_i128 unit = (hf_i128)1 << shift;
            floor_part = hf_floor_div(product, unit);
            fractional = product - floor_part * unit != 0;
        }
        whole += floor_part;
    }
    /* whole + f with f in [0, 1): floor((whole + f) / den) == floor(whole / den) because
     * den is an integer; the strict bound differs only when the value is exactly k*den. */
    if (strict && !fractional) return (int64_t)hf_floor_div(whole - 1, den);
    return (int64_t)hf_floor_div(whole, den);
}

/* ---- Best rational approximation (runs_periodic) ------------------------------------- */
void hf_best_rational(int64_t num, int64_t den, int64_t max_den, int64_t *p_out, int64_t *q_out) {
    /* continued fraction of num/den; convergents p1/q1, previous p0/q0 */
    int64_t p0 = 0, q0 = 1, p1 = 1, q1 = 0, n = num, d = den;
    HF_ASSERT(den > 0 && num >= 0 && num <= den && max_den >= 1, "num=%lld den=%lld",
              (long long)num, (long long)den);
    for (;;) {
        const int64_t a = n / d;
        const int64_t q2 = q0 + a * q1;
        int64_t rem;
        if (q2 > max_den) break;
        {
            const int64_t p2 = p0 + a * p1;
            p0 = p1;
            q0 = q1;
            p1 = p2;
            q1 = q2;
        }
        rem = n - a * d;
        n = d;
        d = rem;
        if (d == 0) {
            *p_out = p1;
            *q_out = q1;
            return;
        } /* exact */
    }
    {
        /* semiconvergent bound1 = (p0 + k p1)/(q0 + k q1) versus convergent p1/q1 */
        const int64_t k = (max_den - q0) / q1;
        const int64_t pb = p0 + k * p1, qb = q0 + k * q1;
        /* |p1/q1 - x| <= |pb/qb - x| with x = num/den, compared exactly */
        hf_i128 e1 = (hf_i128)p1 * den - (hf_i128)num * q1;
        hf_i128 e2 = (hf_i128)pb * den - (hf_i128)num * qb;
        if (e1 < 0) e1 = -e1;
        if (e2 < 0) e2 = -e2;
        if (e1 * qb <= e2 * q1) {
            *p_out = p1;
            *q_out = q1;
        } else {
            *p_out = pb;
            *q_out = qb;
        }
    }
}

/* ---- The exact line of one ray -------------------------------------------------------- */
static int64_t max64(int64_t a, int64_t b) {
    return a > b ? a : b;
}
static int64_t min64(int64_t a, int64_t b) {
    return a < b ? a : b;
}

/* The part of the exact line that depends on the direction alone (and on
 * max_denominator): its lattice scale, the rounded direction's octant and slope. */
HF_INLINE void direction_setup(const double direction[2], int64_t max_denominator,
                               hf_direction *dir) {
    int64_t D[2];
    int k, major;
    dir->key[0] = direction[0];
    dir->key[1] = direction[1];
    dir->key_max_denominator = max_denominator;
    dir->valid = 1;
    dir->vertical = direction[0] == 0.0 && direction[1] == 0.0;
    if (dir->vertical) return;
    dir->scale = direction_scale(direction[0], direction[1]);
    for (k = 0; k < 2; ++k) D[k] = (int64_t)round_even(scale2(direction[k], dir->scale));
    /* octant reduction: major = larger |D| (x on a tie); mirror negative travel */
    major = (D[1] > D[0] ? D[1] : -D[1]) > (D[0] > 0 ? D[0] : -D[0]) ? 1 : 0;
    dir->swap = major;
    dir->mirror_major = D[major] < 0;
    dir->mirror_minor = D[1 - major] < 0;
    dir->time_major = D[major] < 0 ? -D[major] : D[major];
    dir->slope_major = dir->time_major;
    dir->slope_minor = D[1 - major] < 0 ? -D[1 - major] : D[1 - major];
    if (max_denominator > 0) {
        int64_t p, q;
        hf_best_rational(dir->slope_minor, dir->slope_major, max_denominator, &p, &q);
        dir->slope_major = q;
        dir->slope_minor = p;
    }
}

HF_INLINE int line_from_direction(const hf_direction *dir, const double origin[2], double tmin,
                                  double tmax, int32_t nx, int32_t ny, hf_line *L) {
    int64_t O[2];
    int32_t n[2];
    int k, scale, major;
    hf_param lo, hi;
    hf_i128 A, B, T, oa, ob, one = HF_ONE;
    int64_t a0, b0, a1, b1;

    L->swap = 0;
    /* an empty parameter range visits nothing (this also covers tmin = +inf) */
    if (!(tmin < tmax)) return 0;
    n[0] = nx;
    n[1] = ny;
    for (k = 0; k < 2; ++k) O[k] = (int64_t)round_even(origin[k] * (double)HF_ONE);

    /* vertical ray: the one cell under the origin, by the forward rule */
    if (dir->vertical) {
        const int64_t i = (int64_t)hf_floor_div(O[0], one);
        const int64_t j = (int64_t)hf_floor_div(O[1], one);
        if (i < 0 || i >= nx || j < 0 || j >= ny) return 0;
        L->swap = 0;
        L->mirror_major = 0;
        L->mirror_minor = 0;
        L->n_major = nx;
        L->n_minor = ny;
        L->o_major = O[0];
        L->o_minor = O[1];
        L->time_major = 1;
        L->slope_major = 1;
        L->slope_minor = 0;
        L->a0 = L->a1 = (int32_t)i;
        L->b0 = L->b1 = (int32_t)j;
        L->scale = 0;
        return 1;
    }

    /* the direction's share, from the set-up */
    scale = dir->scale;
    L->scale = scale;
    major = dir->swap;
    L->swap = major;
    L->n_major = n[major];
    L->n_minor = n[1 - major];
    L->mirror_major = dir->mirror_major;
    L->mirror_minor = dir->mirror_minor;
    L->o_major = L->mirror_major ? (int64_t)n[major] * HF_ONE - O[major] : O[major];
    L->o_minor = L->mirror_minor ? (int64_t)n[1 - major] * HF_ONE - O[1 - major] : O[1 - major];
    L->time_major = dir->time_major;
    L->slope_major = dir->slope_major;
    L->slope_minor = dir->slope_minor;

    /* tau = t * 2^(16 - scale) */
    lo = param_from_t(tmin, HF_FRAC_BITS - scale);
    hi = param_from_t(tmax, HF_FRAC_BITS - scale);
    if (lo.huge > 0 || hi.huge < 0) return 0;

    A = L->slope_major;
    B = L->slope_minor;
    T = L->time_major;
    oa = L->o_major;
    ob = L->o_minor;

    /* Start cell = cell(p(t0)), t0 = max(tmin, x-entry, y-entry); end cell = cell(p(t1^-)),
     * t1 = min(tmax, x-exit, y-exit). Both indices are non-decreasing in t, so the cell at
     * a maximum of parameters is the componentwise maximum of the cells at each one. */
    a0 = 0;
    a1 = L->n_major - 1;
    if (lo.huge == 0) a0 = max64(a0, lattice_floor(oa, T, lo, one, 0));
    if (hi.huge == 0) a1 = min64(a1, lattice_floor(oa, T, hi, one, 1));
    if (B == 0) {
        /* travel parallel to the major axis: the minor index is constant */
        b0 = b1 = (int64_t)hf_floor_div(ob, one);
        if (b0 < 0 || b0 >= L->n_minor) return 0;
        if (a0 > a1) return 0;
    } else {
        const hf_i128 minor_at_major0 = ob * A - oa * B; /* (A 2^16) * y where x = 0 */
        const hf_i128 major_at_minor0 = oa * B - ob * A; /* (B 2^16) * x where y = 0 */
        const hf_i128 na = (hf_i128)L->n_major * one, nb = (hf_i128)L->n_minor * one;
        /* the entry along one axis must precede the exit along the other */
        if (!(minor_at_major0 < nb * A)) return 0;
        if (!(major_at_minor0 < na * B)) return 0;
        b0 = max64(0, (int64_t)hf_floor_div(minor_at_major0, A * one));
        a0 = max64(a0, (int64_t)hf_floor_div(major_at_minor0, B * one));
        b1 = min64(L->n_minor - 1, (int64_t)hf_floor_div(minor_at_major0 + na * B - 1, A * one));
        a1 = min64(a1, (int64_t)hf_floor_div(major_at_minor0 + nb * A - 1, B * one));
        if (lo.huge == 0) b0 = max64(b0, lattice_floor(ob * A, T * B, lo, A * one, 0));
        if (hi.huge == 0) b1 = min64(b1, lattice_floor(ob * A, T * B, hi, A * one, 1));
        /* The remaining conditions for t0 < t1 (tmin before both exits, tmax after both
         * entries) are exactly a0 <= a1 and b0 <= b1 term by term. */
        if (a0 > a1 || b0 > b1) return 0;
    }
    HF_ASSERT(a0 >= 0 && a0 <= a1 && a1 < L->n_major && b0 >= 0 && b0 <= b1 && b1 < L->n_minor,
              "a0=%lld a1=%lld b0=%lld b1=%lld", (long long)a0, (long long)a1, (long long)b0,
              (long long)b1);
    L->a0 = (int32_t)a0;
    L->a1 = (int32_t)a1;
    L->b0 = (int32_t)b0;
    L->b1 = (int32_t)b1;
    return 1;
}

/* The exact line of one ray, its direction's share set up afresh. */
int hf_line_exact(const double origin[2], const double direction[2], double tmin, double tmax,
                  int32_t nx, int32_t ny, int64_t max_denominator, hf_line *L) {
    hf_direction dir;
    direction_setup(direction, max_denominator, &dir);
    return line_from_direction(&dir, origin, tmin, tmax, nx, ny, L);
}

/* The same, the direction's share taken from `shared` when it was set up for this very
 * direction (bit for bit: -0.0 and 0.0 give one line but need not be told apart) and
 * max_denominator, else set up there for the rays that follow. */
int hf_line_shared(hf_direction *shared, const double origin[2], const double direction[2],
                   double tmin, double tmax, int32_t nx, int32_t ny, int64_t max_denominator,
                   hf_line *L) {
    if (!(shared->valid && memcmp(shared->key, direction, sizeof shared->key) == 0 &&
          shared->key_max_denominator == max_denominator))
        direction_setup(direction, max_denominator, shared);
    return line_from_direction(shared, origin, tmin, tmax, nx, ny, L);
}
