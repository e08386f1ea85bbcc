/* The binding's shared argument reader: arrays checked for dtype, layout and size, the rays
 * of a batch, the timed GIL-free section and the status messages (args.h). */
#define HF_BINDING_ARGS_C
#include "binding/args.h"

void hf_timed_begin(hf_timed_section *section) {
    section->thread = PyEval_SaveThread();
    clock_gettime(CLOCK_MONOTONIC, &section->start);
}

long long hf_timed_end(hf_timed_section *section) {
    struct timespec stop;
    clock_gettime(CLOCK_MONOTONIC, &stop);
    PyEval_RestoreThread(section->thread);
    return (long long)(stop.tv_sec - section->start.tv_sec) * 1000000000LL +
           (long long)(stop.tv_nsec - section->start.tv_nsec);
}

const char *hf_status_text(int status) {
    switch (status) {
    case HF_ERR_CAPACITY: return "an output buffer does not match the counting pass";
    case HF_ERR_INTERNAL: return "an exact walk missed its computed last cell";
    case HF_ERR_ARGUMENT: return "unknown kernel or mode";
    case HF_ERR_MEMORY: return "out of memory for a kernel's or renderer's scratch";
    default: return "unknown error";
    }
}
