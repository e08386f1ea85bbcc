/* Dispatch of a batch to its kernel. */
#include "walks/walk.h"

int hf_walk_batch(int kernel, int mode, hf_batch *batch) {
    hf_pattern pattern;
    if (mode < 0 || mode >= HF_N_MODES) return HF_ERR_ARGUMENT;
    batch->bad_ray = -1;
    switch (kernel) {
    case HF_DDA: return hf_batch_dda(batch, mode, NULL);
    case HF_DDA_F32: return hf_batch_dda_f32(batch, mode, NULL);
    case HF_MIDPOINT: return hf_batch_midpoint(batch, mode, NULL);
    case HF_RUNS: return hf_batch_runs(batch, mode, NULL);
    case HF_RUNS_F64: return hf_batch_runs_f64(batch, mode, NULL);
    case HF_RUNS_PERIODIC:
        if (batch->pattern == NULL || batch->max_denominator < 1) return HF_ERR_ARGUMENT;
        pattern.p = 0;
        pattern.q = 0;
        pattern.position_step = 0;
        pattern.lengths = batch->pattern;
        return hf_batch_runs_periodic(batch, mode, &pattern);
    default: return HF_ERR_ARGUMENT;
    }
}
