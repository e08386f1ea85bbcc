/* Range maxima over the rows and the columns of the cell maxima: the run kernels' cull
 * (cell_test.h, hf_hit_run). */
#ifndef HFTRACE_RMQ_H
#define HFTRACE_RMQ_H

#include <stdint.h>

/* Range maximum over one line (a row or a column) of cell maxima, answered in O(1) once
 * the range spans two blocks of 2^block_shift cells: the suffix maximum of the first
 * block, the prefix maximum of the last, and a sparse table over the whole blocks in
 * between. Inside one block the few cells are scanned. */
typedef struct {
    int32_t n_lines, length, block_shift, n_blocks, n_levels;
    const float *values; /* [line][length]                       */
    const float *prefix; /* [line][length]: max from block start */
    const float *suffix; /* [line][length]: max to block end     */
    const float *sparse; /* [line][level][n_blocks]              */
} hf_rmq;

/* ---- range maximum --------------------------------------------------------------------- */
static inline float hf_rmq_query(const hf_rmq *q, int32_t line, int32_t lo, int32_t hi) {
    const int32_t shift = q->block_shift;
    const int32_t blo = lo >> shift, bhi = hi >> shift;
    const float *values = q->values + (int64_t)line * q->length;
    float best;
    if (blo == bhi) {
        int32_t k;
        best = values[lo];
        for (k = lo + 1; k <= hi; ++k) best = values[k] > best ? values[k] : best;
        return best;
    }
    {
        const float a = q->suffix[(int64_t)line * q->length + lo];
        const float b = q->prefix[(int64_t)line * q->length + hi];
        best = a > b ? a : b;
    }
    if (bhi - blo >= 2) {
        /* whole blocks blo+1 .. bhi-1: two overlapping power-of-two windows */
        const int32_t first = blo + 1, count = bhi - blo - 1;
        int32_t level = 0;
        const float *table;
        float c, d;
        while ((2 << level) <= count) ++level;
        table = q->sparse + ((int64_t)line * q->n_levels + level) * q->n_blocks;
        c = table[first];
        d = table[bhi - (1 << level)];
        best = best > c ? best : c;
        best = best > d ? best : d;
    }
    return best;
}

#endif
