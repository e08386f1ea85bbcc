/* packet_maxmip: the dda_maxmip walk (maxmip.h) of up to HF_PACKET_MAX neighbouring rays
 * at once (packets: Wald, Slusallek, Benthin & Wagner 2001; on the maximum mipmap of
 * Tevs, Ihrke & Seidel 2008).
 *
 * Each ray keeps its own walk state, and the rays whose walks stand at the same level
 * over the same tile form a group: the tile's maximum is read once for the group, the
 * rays' exit parameters of that tile are computed side by side (optionally in SIMD
 * lanes), and every ray then takes its own step (skip and climb, descend, or walk the floor tile)
 * with the per-ray kernel's functions. A group whose rays all skip or all descend stays together;
 * rays whose steps differ land in different tiles or levels and form groups of their own,
 * and a ray alone in its tile leaves the packet and finishes its walk with the per-ray
 * loop (hf_mip_walk_alone) from its current state. Every ray therefore takes exactly the
 * steps dda_maxmip takes, with the same arithmetic: t, cell, normal and the statistics
 * are bit-identical to dda_maxmip's. */
#include <math.h>
#include <stdint.h>
#include <string.h>
#include "hierarchies/packet.h"
#include "surfaces/hitbatch.h"
#include "hierarchies/maxmip.h"

/* HF_PACKET_SIMD=1 (GCC or clang; build with CFLAGS=-DHF_PACKET_SIMD=1): the exit
 * parameters of a group in vector extensions, 4 doubles per vector (two SSE2 operations
 * each on the default x86-64 target); 0, the default: the portable scalar loop, per ray of
 * the group. Both compute the same IEEE operations (no contraction: the build has no FMA),
 * so outputs never depend on the choice. The vectors do not pay: counted on render's
 * camera rays (fbm 1024^2, 1280 x 720, every 48th row), packet_maxmip at width 4 runs
 * 2122 instructions per ray with them and 2116 without (README, "Coherent batches"). */
#ifndef HF_PACKET_SIMD
#define HF_PACKET_SIMD 0
#endif
#if HF_PACKET_SIMD && !(defined(__GNUC__) || defined(__clang__))
#error "HF_PACKET_SIMD needs GCC or clang vector extensions"
#endif

static int lowest_bit(unsigned m) {
#if defined(__GNUC__) || defined(__clang__)
    return __builtin_ctz(m);
#else
    int k = 0;
    while (!(m & 1u)) {
        m >>= 1;
        ++k;
    }
    return k;
#endif
}

/* Every lane's exit parameters from tile (tile_i, tile_j) at `level`, as hf_mip_exit_x
 * and hf_mip_exit_y compute them: the face (tile + f) << level is formed as
 * (tile << level) + f * 2^level, exact in double (both are integers below 2^53), so
 * ((double)face - o) * inv rounds alike; a lane not moving along an axis gets inf. */
#if HF_PACKET_SIMD
#define HF_LANES   4
#define HF_VECTORS (HF_PACKET_MAX / HF_LANES)

/* The lanes of a packet, structure of arrays: what the exit parameters read per ray. */
typedef struct {
    double ox[HF_PACKET_MAX], oy[HF_PACKET_MAX];          /* origin                      */
    double inv_x[HF_PACKET_MAX], inv_y[HF_PACKET_MAX];    /* inverse direction, 0 unused */
    double fx[HF_PACKET_MAX], fy[HF_PACKET_MAX];          /* exit face offset, 0 or 1    */
    int64_t keep_x[HF_PACKET_MAX], keep_y[HF_PACKET_MAX]; /* all ones: the ray moves along it */
} hf_lanes;

static void lanes_set(hf_lanes *l, int k, const hf_mip_ray *r) {
    l->ox[k] = r->ox;
    l->oy[k] = r->oy;
    l->inv_x[k] = r->has_x ? r->inv_x : 0.0;
    l->inv_y[k] = r->has_y ? r->inv_y : 0.0;
    l->fx[k] = (double)r->fx;
    l->fy[k] = (double)r->fy;
    l->keep_x[k] = r->has_x ? -1 : 0;
    l->keep_y[k] = r->has_y ? -1 : 0;
}

typedef double hf_v4d __attribute__((vector_size(32)));
typedef int64_t hf_v4i __attribute__((vector_size(32)));

static void lanes_exits(const hf_lanes *l, int nvec, int32_t tile_i, int32_t tile_j, int level,
                        double *t_exit_x, double *t_exit_y) {
    const double size = (double)((int64_t)1 << level);
    const double base_x = (double)((int64_t)tile_i << level);
    const double base_y = (double)((int64_t)tile_j << level);
    const hf_v4i inf = {0x7ff0000000000000LL, 0x7ff0000000000000LL, 0x7ff0000000000000LL,
                        0x7ff0000000000000LL};
    int v;
    for (v = 0; v < nvec; ++v) {
        hf_v4d ox, oy, ix, iy, fx, fy, tx, ty;
        hf_v4i kx, ky;
        memcpy(&ox, l->ox + HF_LANES * v, sizeof ox);
        memcpy(&oy, l->oy + HF_LANES * v, sizeof oy);
        memcpy(&ix, l->inv_x + HF_LANES * v, sizeof ix);
        memcpy(&iy, l->inv_y + HF_LANES * v, sizeof iy);
        memcpy(&fx, l->fx + HF_LANES * v, sizeof fx);
        memcpy(&fy, l->fy + HF_LANES * v, sizeof fy);
        memcpy(&kx, l->keep_x + HF_LANES * v, sizeof kx);
        memcpy(&ky, l->keep_y + HF_LANES * v, sizeof ky);
        tx = ((base_x + fx * size) - ox) * ix;
        ty = ((base_y + fy * size) - oy) * iy;
        /* a bitwise select, so a kept lane's value passes unchanged (even a -0) */
        tx = (hf_v4d)(((hf_v4i)tx & kx) | (inf & ~kx));
        ty = (hf_v4d)(((hf_v4i)ty & ky) | (inf & ~ky));
        memcpy(t_exit_x + HF_LANES * v, &tx, sizeof tx);
        memcpy(t_exit_y + HF_LANES * v, &ty, sizeof ty);
    }
}
#endif

void hf_packet_maxmip(hf_hit *hits, unsigned members, const hf_hit_batch *b) {
    hf_mip_ray r[HF_PACKET_MAX];
    hf_mip_walk w[HF_PACKET_MAX];
    unsigned active = members, rest;
#if HF_PACKET_SIMD
    hf_lanes lanes;
    int nvec = 1;
    memset(&lanes, 0, sizeof lanes);
#endif
    for (rest = members; rest; rest &= rest - 1) {
        const int k = lowest_bit(rest);
        hf_mip_setup(&hits[k], b, &r[k], &w[k]);
#if HF_PACKET_SIMD
        lanes_set(&lanes, k, &r[k]);
        if (k >= HF_LANES) nvec = HF_VECTORS;
#endif
    }
    while (active) {
        const int lead = lowest_bit(active);
        const int level = w[lead].level;
        const int32_t tile_i = w[lead].i >> level, tile_j = w[lead].j >> level;
        unsigned group = 1u << lead;
        /* the group: the active rays at the leader's level over the leader's tile */
        for (rest = active & (active - 1); rest; rest &= rest - 1) {
            const int k = lowest_bit(rest);
            if (w[k].level == level && (w[k].i >> level) == tile_i && (w[k].j >> level) == tile_j)
                group |= 1u << k;
        }
        if (group == 1u << lead) {
            /* alone: the ray leaves the packet and ends its walk on its own */
            (void)hf_mip_walk_alone(&hits[lead], b, &r[lead], &w[lead], 1);
            active &= ~group;
            continue;
        }
        {
            /* the tile, tested once for the group: one read of its maximum */
            const double tile_max = hf_mip_tile_max(b, level, tile_i, tile_j);
            double t_exit_x[HF_PACKET_MAX], t_exit_y[HF_PACKET_MAX];
#if HF_PACKET_SIMD
            lanes_exits(&lanes, nvec, tile_i, tile_j, level, t_exit_x, t_exit_y);
#else
            for (rest = group; rest; rest &= rest - 1) {
                const int k = lowest_bit(rest);
                t_exit_x[k] = hf_mip_exit_x(&r[k], tile_i, level);
                t_exit_y[k] = hf_mip_exit_y(&r[k], tile_j, level);
            }
#endif
            for (rest = group; rest; rest &= rest - 1) {
                const int k = lowest_bit(rest);
                hf_mip_walk *wk = &w[k];
                const hf_mip_ray *rk = &r[k];
                if (wk->guard > rk->guard_max) {
                    /* the walk gives up, as the per-ray loop would: a miss */
                    active &= ~(1u << k);
                } else {
                    const hf_mip_tile e =
                        hf_mip_tile_of(rk, tile_i, tile_j, t_exit_x[k], t_exit_y[k]);
                    const int skip =
                        hf_tile_zlow(rk->oz, rk->dz, rk->descending, wk->t, e.t_exit) > tile_max;
                    if (hf_mip_iterate(&hits[k], rk, wk, &e, skip, 1) >= 0) active &= ~(1u << k);
                }
            }
        }
    }
}
