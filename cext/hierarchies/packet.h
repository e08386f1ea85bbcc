/* packet_maxmip (packet.c): the max-mipmap walk of several neighbouring rays at once. */
#ifndef HFTRACE_PACKET_H
#define HFTRACE_PACKET_H

#include "surfaces/hitbatch.h"

/* packet_maxmip: the dda_maxmip walks of the rays of hits[] whose bit is set in
 * `members` (clipped and prepared, each with a max-mipmap walk to do), together; each
 * hits[k] ends as dda_maxmip leaves it (packet.c). */
void hf_packet_maxmip(hf_hit *hits, unsigned members, const hf_hit_batch *b);

#endif
