/* The binding of the terrain products' kernels (terrain/): horizons, viewsheds. */
#include "binding/args.h"
#include "terrain/terrain.h"
#include "terrain/horizon_fast.h"

/* ---- terrain products ------------------------------------------------------------- */

/* heights: a C-contiguous float64 (rows, cols) array with both sides in [2, 2^24]. */
static int get_heights(PyObject *object, const double **data, int64_t *rows, int64_t *cols) {
    npy_intp shape[2];
    void *p;
    if (!hf_arg_grid_shape(object, "heights", HF_GRID_VERTICES, shape)) return 0;
    *rows = shape[0];
    *cols = shape[1];
    if (!hf_arg_array(object, "heights", NPY_FLOAT64, -1, 0, 0, &p, NULL)) return 0;
    *data = (const double *)p;
    return 1;
}

static int vertex_range(long long start, long long stop, int64_t rows, int64_t cols) {
    if (start < 0 || stop < start || stop > (long long)(rows * cols)) {
        PyErr_Format(PyExc_ValueError, "vertex range [%lld, %lld) outside [0, %lld]", start, stop,
                     (long long)(rows * cols));
        return 0;
    }
    return 1;
}

/* Optional mipmap (None or data, offset, rows, cols), checked against the cell grid. */
static int get_mip(PyObject *o_mip, int64_t rows, int64_t cols, hf_hz_mip *mip, int *has) {
    PyObject *o_data, *o_off, *o_r, *o_c;
    npy_intp n_data, n_levels;
    void *p;
    *has = 0;
    if (o_mip == Py_None) return 1;
    if (!PyArg_ParseTuple(o_mip, "OOOO", &o_data, &o_off, &o_r, &o_c)) return 0;
    if (!hf_arg_array(o_data, "mip data", NPY_FLOAT64, -1, 0, 0, &p, &n_data)) return 0;
    mip->data = (const double *)p;
    if (!hf_arg_array(o_off, "mip offset", NPY_INT64, -1, 0, 0, &p, &n_levels)) return 0;
    mip->offset = (const int64_t *)p;
    if (!hf_arg_array(o_r, "mip rows", NPY_INT64, n_levels, 0, 0, &p, NULL)) return 0;
    mip->rows = (const int64_t *)p;
    if (!hf_arg_array(o_c, "mip cols", NPY_INT64, n_levels, 0, 0, &p, NULL)) return 0;
    mip->cols = (const int64_t *)p;
    if (n_levels < 1 || n_levels > 62) {
        PyErr_SetString(PyExc_ValueError, "mip: 1 to 62 levels");
        return 0;
    }
    for (npy_intp L = 0; L < n_levels; L++) {
        int64_t need_r = ((rows - 1) + ((int64_t)1 << L) - 1) >> L;
        int64_t need_c = ((cols - 1) + ((int64_t)1 << L) - 1) >> L;
        if (mip->rows[L] < need_r || mip->cols[L] < need_c || mip->offset[L] < 0 ||
            mip->offset[L] + mip->rows[L] * mip->cols[L] > n_data) {
            PyErr_Format(PyExc_ValueError, "mip: level %ld does not cover the grid", (long)L);
            return 0;
        }
    }
    if (mip->rows[n_levels - 1] != 1 || mip->cols[n_levels - 1] != 1) {
        PyErr_SetString(PyExc_ValueError, "mip: the top level must be one tile");
        return 0;
    }
    mip->n_levels = (int32_t)n_levels;
    *has = 1;
    return 1;
}

static PyObject *stats_tuple(const hf_hz_stats *s, long long elapsed_ns) {
    return Py_BuildValue("LLL", elapsed_ns, (long long)s->cells, (long long)s->skips);
}

/* What every terrain entry point reads first: the heights, the range of vertices it
 * computes (vertex entry points), and the optional mipmap (the walks). */
typedef struct {
    const double *H;
    int64_t rows, cols;
    hf_hz_mip mip;
    int has_mip;
} terrain_field;

/* The heights; with check_range, the vertex range [start, stop) inside them; with o_mip
 * not NULL, the mipmap argument (None or its four arrays) over them. */
static int get_field(PyObject *o_h, int check_range, long long start, long long stop,
                     PyObject *o_mip, terrain_field *f) {
    f->has_mip = 0;
    if (!get_heights(o_h, &f->H, &f->rows, &f->cols)) return 0;
    if (check_range && !vertex_range(start, stop, f->rows, f->cols)) return 0;
    return o_mip == NULL || get_mip(o_mip, f->rows, f->cols, &f->mip, &f->has_mip);
}

/* An output (`out`, the chain's `occ`): one element of `type` per vertex (hf_arg_out). */
static int get_vertex_out(PyObject *object, const char *name, const terrain_field *f, int type,
                          void **data) {
    return hf_arg_out(object, name, type, f->rows * f->cols, 0, data);
}

/* The mipmap for the kernel: NULL when the call passed None. */
static const hf_hz_mip *mip_of(const terrain_field *f) {
    return f->has_mip ? &f->mip : NULL;
}

static int check_kappa(double kappa) {
    if (!isfinite(kappa)) {
        PyErr_SetString(PyExc_ValueError, "kappa: expected a finite curvature");
        return 0;
    }
    return 1;
}

/* A walk's horizontal direction and reach. */
static int check_direction(double dx, double dy, double max_distance) {
    if (!isfinite(dx) || !isfinite(dy) || (dx == 0 && dy == 0) || isnan(max_distance)) {
        PyErr_SetString(PyExc_ValueError, "direction: finite and nonzero; max_distance not NaN");
        return 0;
    }
    return 1;
}

/* A viewshed's observer (ox, oy) on the footprint and its finite heights; `other_bad`: a
 * further argument of the caller's is invalid (the same message). */
static int check_observer(const terrain_field *f, double ox, double oy, double z0,
                          double target_height, double drop, int other_bad) {
    if (!(ox >= 0 && ox <= (double)(f->cols - 1) && oy >= 0 && oy <= (double)(f->rows - 1)) ||
        !isfinite(z0) || !isfinite(target_height) || !isfinite(drop) || other_bad) {
        PyErr_SetString(PyExc_ValueError, "observer: outside the footprint, or a non-finite value");
        return 0;
    }
    return 1;
}

/* A pattern's interpolation arrays: dx_a, dy_a, dx_b, dy_b (int64) and w (float64), n
 * elements each: breakpoint e lies between the vertices at offsets (dx_a, dy_a) and
 * (dx_b, dy_b) with weight w. */
typedef struct {
    const int64_t *dxa, *dya, *dxb, *dyb;
    const double *w;
} lerp_arrays;

static int get_lerp_arrays(PyObject *o_dxa, PyObject *o_dya, PyObject *o_dxb, PyObject *o_dyb,
                           PyObject *o_w, npy_intp n, lerp_arrays *l) {
    PyObject *const objects[4] = {o_dxa, o_dya, o_dxb, o_dyb};
    static const char *const names[4] = {"dx_a", "dy_a", "dx_b", "dy_b"};
    const int64_t **ints[4] = {&l->dxa, &l->dya, &l->dxb, &l->dyb};
    void *p;
    for (int k = 0; k < 4; k++) {
        if (!hf_arg_array(objects[k], names[k], NPY_INT64, n, 0, 0, &p, NULL)) return 0;
        *ints[k] = (const int64_t *)p;
    }
    if (!hf_arg_array(o_w, "w", NPY_FLOAT64, n, 0, 0, &p, NULL)) return 0;
    l->w = (const double *)p;
    return 1;
}

/* The breakpoints' two vertices as offsets in the field (dy * cols + dx), newly allocated
 * (the caller frees both); 0 with MemoryError set. */
static int lerp_offsets(const lerp_arrays *l, npy_intp n, int64_t cols, int64_t **off_a,
                        int64_t **off_b) {
    *off_a = malloc((size_t)(n ? n : 1) * sizeof **off_a);
    *off_b = malloc((size_t)(n ? n : 1) * sizeof **off_b);
    if (!*off_a || !*off_b) {
        free(*off_a);
        free(*off_b);
        PyErr_NoMemory();
        return 0;
    }
    for (npy_intp e = 0; e < n; e++) {
        (*off_a)[e] = l->dya[e] * cols + l->dxa[e];
        (*off_b)[e] = l->dyb[e] * cols + l->dxb[e];
    }
    return 1;
}

PyDoc_STRVAR(horizon_pattern_doc,
             "horizon_pattern(heights, inv_t, dx_a, dy_a, dx_b, dy_b, w, limit_x, limit_y,\n"
             "                end_k, end_f, end_inv_t, zmax, stop_every, start, stop, out,\n"
             "                kappa=0.0) -> (ns, 0, 0)\n\nHorizon tangents by one shared pattern\n"
             "(octant frame); kappa: curvature. Private: use algos.horizon.");

static PyObject *horizon_pattern(PyObject *self, PyObject *args) {
    PyObject *o_h, *o_inv, *o_dxa, *o_dya, *o_dxb, *o_dyb, *o_w, *o_lx, *o_ly, *o_out;
    long long end_k, stop_every, start, stop;
    double end_f, end_inv_t, zmax, kappa = 0.0;
    int64_t *off_a = NULL, *off_b = NULL;
    const int64_t *lx, *ly;
    lerp_arrays lerp;
    npy_intp n;
    void *p;
    hf_hz_pattern pat;
    hf_hz_stats st = {0, 0};
    hf_timed_section section;
    long long elapsed_ns;
    int64_t reach = 0;
    terrain_field f;
    (void)self;
    if (!PyArg_ParseTuple(args, "OOOOOOOOOLdddLLLO|d", &o_h, &o_inv, &o_dxa, &o_dya, &o_dxb, &o_dyb,
                          &o_w, &o_lx, &o_ly, &end_k, &end_f, &end_inv_t, &zmax, &stop_every,
                          &start, &stop, &o_out, &kappa))
        return NULL;
    if (!check_kappa(kappa)) return NULL;
    if (!get_field(o_h, 1, start, stop, NULL, &f)) return NULL;
    if (!hf_arg_array(o_inv, "inv_t", NPY_FLOAT64, -1, 0, 0, &p, &n)) return NULL;
    pat.inv_t = (const double *)p;
    if (!get_lerp_arrays(o_dxa, o_dya, o_dxb, o_dyb, o_w, n, &lerp)) return NULL;
    pat.w = lerp.w;
    if (!hf_arg_array(o_lx, "limit_x", NPY_INT64, f.cols, 0, 0, &p, NULL)) return NULL;
    lx = (const int64_t *)p;
    if (!hf_arg_array(o_ly, "limit_y", NPY_INT64, f.rows, 0, 0, &p, NULL)) return NULL;
    ly = (const int64_t *)p;
    if (!get_vertex_out(o_out, "out", &f, NPY_FLOAT64, &p)) return NULL;
    if (end_k < -1 || end_k + 1 >= (long long)n + (end_k < 0)) {
        PyErr_SetString(PyExc_ValueError, "end_k: outside the pattern");
        return NULL;
    }
    /* memory safety: every breakpoint a limit admits reads inside the field */
    for (int64_t k = 0; k < f.cols; k++)
        if (lx[k] < 0 || lx[k] > n || (k && lx[k] < lx[k - 1])) reach = -1;
    for (int64_t k = 0; k < f.rows; k++)
        if (ly[k] < 0 || ly[k] > n || (k && ly[k] < ly[k - 1])) reach = -1;
    if (reach == 0) {
        int64_t e = 0, mxx = 0, myy = 0;
        for (int64_t k = 0; k < f.cols && reach == 0; k++) {
            for (; e < lx[k]; e++) {
                int64_t ax = lerp.dxa[e] > lerp.dxb[e] ? lerp.dxa[e] : lerp.dxb[e];
                if (lerp.dxa[e] < 0 || lerp.dxb[e] < 0 || lerp.dya[e] < 0 || lerp.dyb[e] < 0)
                    reach = -1;
                if (ax > mxx) mxx = ax;
            }
            if (mxx > k) reach = -1;
        }
        e = 0;
        for (int64_t k = 0; k < f.rows && reach == 0; k++) {
            for (; e < ly[k]; e++) {
                int64_t ay = lerp.dya[e] > lerp.dyb[e] ? lerp.dya[e] : lerp.dyb[e];
                if (ay > myy) myy = ay;
            }
            if (myy > k) reach = -1;
        }
    }
    if (reach < 0) {
        PyErr_SetString(PyExc_ValueError, "pattern: a limit admits a breakpoint outside the field");
        return NULL;
    }
    if (!lerp_offsets(&lerp, n, f.cols, &off_a, &off_b)) return NULL;
    pat.n = n;
    pat.off_a = off_a;
    pat.off_b = off_b;
    pat.limit_x = lx;
    pat.limit_y = ly;
    pat.end_k = end_k;
    pat.end_f = end_f;
    pat.end_inv_t = end_inv_t;
    hf_timed_begin(&section);
    hf_horizon_pattern(f.H, f.rows, f.cols, &pat, zmax, stop_every, kappa, start, stop,
                       (double *)p);
    elapsed_ns = hf_timed_end(&section);
    free(off_a);
    free(off_b);
    return stats_tuple(&st, elapsed_ns);
}

PyDoc_STRVAR(horizon_sweep_doc,
             "horizon_sweep(heights, q, p, tfrac, dx_a, dy_a, dx_b, dy_b, w, mx, my, norm,\n"
             "              k_lo, k_hi, out) -> (ns, 0, 0)\n\nHorizon tangents of the vertices on\n"
             "lines [k_lo, k_hi) by the rational sweep (octant frame). Private: use\n"
             "algos.horizon.");

static PyObject *horizon_sweep(PyObject *self, PyObject *args) {
    PyObject *o_h, *o_tf, *o_dxa, *o_dya, *o_dxb, *o_dyb, *o_w, *o_mx, *o_my, *o_out;
    long long q, pp, k_lo, k_hi;
    double norm;
    const double *tf;
    const int64_t *mx, *my;
    lerp_arrays lerp;
    npy_intp n;
    void *p, *out;
    int status;
    hf_hz_stats st = {0, 0};
    hf_timed_section section;
    long long elapsed_ns;
    terrain_field f;
    (void)self;
    if (!PyArg_ParseTuple(args, "OLLOOOOOOOOdLLO", &o_h, &q, &pp, &o_tf, &o_dxa, &o_dya, &o_dxb,
                          &o_dyb, &o_w, &o_mx, &o_my, &norm, &k_lo, &k_hi, &o_out))
        return NULL;
    if (!get_field(o_h, 0, 0, 0, NULL, &f)) return NULL;
    if (q < 1 || pp < 0 || pp > q || q > HF_MAX_GRID_SIDE) {
        PyErr_SetString(PyExc_ValueError, "direction: need q >= p >= 0 and 1 <= q <= 2^24");
        return NULL;
    }
    if (k_lo < 0 || k_hi < k_lo || k_hi > q * (f.rows - 1) + pp * (f.cols - 1) + 1) {
        PyErr_SetString(PyExc_ValueError, "k_lo, k_hi: the line range is outside the field");
        return NULL;
    }
    if (!hf_arg_array(o_tf, "tfrac", NPY_FLOAT64, -1, 0, 0, &p, &n)) return NULL;
    tf = (const double *)p;
    if (!get_lerp_arrays(o_dxa, o_dya, o_dxb, o_dyb, o_w, n, &lerp)) return NULL;
    if (!hf_arg_array(o_mx, "mx", NPY_INT64, n, 0, 0, &p, NULL)) return NULL;
    mx = (const int64_t *)p;
    if (!hf_arg_array(o_my, "my", NPY_INT64, n, 0, 0, &p, NULL)) return NULL;
    my = (const int64_t *)p;
    if (!get_vertex_out(o_out, "out", &f, NPY_FLOAT64, &out)) return NULL;
    if (n < 1 || mx[n - 1] != q || my[n - 1] != pp || lerp.dxa[n - 1] != q ||
        lerp.dya[n - 1] != pp || lerp.dxb[n - 1] != q || lerp.dyb[n - 1] != pp) {
        PyErr_SetString(PyExc_ValueError, "pattern: the last breakpoint must be the next vertex");
        return NULL;
    }
    for (npy_intp e = 0; e < n; e++) {
        if (lerp.dxa[e] < 0 || lerp.dya[e] < 0 || lerp.dxb[e] < 0 || lerp.dyb[e] < 0 ||
            lerp.dxa[e] > mx[e] || lerp.dxb[e] > mx[e] || lerp.dya[e] > my[e] ||
            lerp.dyb[e] > my[e] || mx[e] > q || my[e] > pp || !(tf[e] > 0.0 && tf[e] <= 1.0) ||
            (e && !(tf[e] > tf[e - 1]))) {
            PyErr_Format(PyExc_ValueError, "pattern: breakpoint %ld is inconsistent", (long)e);
            return NULL;
        }
    }
    hf_timed_begin(&section);
    status = hf_horizon_sweep(f.H, f.rows, f.cols, q, pp, n, tf, lerp.dxa, lerp.dya, lerp.dxb,
                              lerp.dyb, lerp.w, mx, my, norm, k_lo, k_hi, (double *)out);
    elapsed_ns = hf_timed_end(&section);
    if (status) return PyErr_NoMemory();
    return stats_tuple(&st, elapsed_ns);
}

PyDoc_STRVAR(horizon_walk_doc,
             "horizon_walk(heights, mip, dx, dy, max_distance, start, stop, out, kappa=0.0)\n"
             "-> (ns, cells, skips)\n\nPer-vertex horizon walks (mip None: every cell);\n"
             "kappa: curvature. Private: use algos.horizon.");

static PyObject *horizon_walk(PyObject *self, PyObject *args) {
    PyObject *o_h, *o_mip, *o_out;
    double dx, dy, max_distance, kappa = 0.0;
    long long start, stop;
    void *out;
    hf_hz_stats st = {0, 0};
    hf_timed_section section;
    long long elapsed_ns;
    terrain_field f;
    (void)self;
    if (!PyArg_ParseTuple(args, "OOdddLLO|d", &o_h, &o_mip, &dx, &dy, &max_distance, &start, &stop,
                          &o_out, &kappa))
        return NULL;
    if (!check_kappa(kappa)) return NULL;
    if (!get_field(o_h, 1, start, stop, o_mip, &f)) return NULL;
    if (!check_direction(dx, dy, max_distance)) return NULL;
    if (!get_vertex_out(o_out, "out", &f, NPY_FLOAT64, &out)) return NULL;
    hf_timed_begin(&section);
    hf_horizon_walk(f.H, f.rows, f.cols, mip_of(&f), dx, dy, max_distance, kappa, start, stop,
                    (double *)out, &st);
    elapsed_ns = hf_timed_end(&section);
    return stats_tuple(&st, elapsed_ns);
}

PyDoc_STRVAR(horizon_rows_doc,
             "horizon_rows(heights, inv_t, dx_a, dy_a, dx_b, dy_b, w, rx, ry, sx, sy, n_main,\n"
             "             end_k, end_f, end_inv_t, row_start, row_stop, out) -> (ns, 0, 0)\n\n"
             "Horizon tangents of rows [row_start, row_stop) by one shared pattern in the\n"
             "grid's own frame, row by row. Private: use algos.horizon.");

static PyObject *horizon_rows(PyObject *self, PyObject *args) {
    PyObject *o_h, *o_inv, *o_dxa, *o_dya, *o_dxb, *o_dyb, *o_w, *o_rx, *o_ry, *o_out;
    long long n_main, end_k, row_start, row_stop;
    int sx, sy;
    double end_f, end_inv_t;
    const double *inv_t;
    const int64_t *rx, *ry;
    lerp_arrays lerp;
    int64_t *off_a = NULL, *off_b = NULL;
    npy_intp n;
    void *p, *out;
    hf_hz_stats st = {0, 0};
    hf_timed_section section;
    long long elapsed_ns;
    terrain_field f;
    (void)self;
    if (!PyArg_ParseTuple(args, "OOOOOOOOOiiLLddLLO", &o_h, &o_inv, &o_dxa, &o_dya, &o_dxb, &o_dyb,
                          &o_w, &o_rx, &o_ry, &sx, &sy, &n_main, &end_k, &end_f, &end_inv_t,
                          &row_start, &row_stop, &o_out))
        return NULL;
    if (!get_field(o_h, 0, 0, 0, NULL, &f)) return NULL;
    if (row_start < 0 || row_stop < row_start || row_stop > (long long)f.rows) {
        PyErr_Format(PyExc_ValueError, "row range [%lld, %lld) outside [0, %lld]", row_start,
                     row_stop, (long long)f.rows);
        return NULL;
    }
    if ((sx != 1 && sx != -1) || (sy != 1 && sy != -1)) {
        PyErr_SetString(PyExc_ValueError, "sx, sy: expected +1 or -1");
        return NULL;
    }
    if (!hf_arg_array(o_inv, "inv_t", NPY_FLOAT64, -1, 0, 0, &p, &n)) return NULL;
    inv_t = (const double *)p;
    if (!get_lerp_arrays(o_dxa, o_dya, o_dxb, o_dyb, o_w, n, &lerp)) return NULL;
    if (!hf_arg_array(o_rx, "rx", NPY_INT64, n, 0, 0, &p, NULL)) return NULL;
    rx = (const int64_t *)p;
    if (!hf_arg_array(o_ry, "ry", NPY_INT64, n, 0, 0, &p, NULL)) return NULL;
    ry = (const int64_t *)p;
    if (!get_vertex_out(o_out, "out", &f, NPY_FLOAT64, &out)) return NULL;
    if (n_main < 0 || n_main > (long long)n || end_k < -1 ||
        (end_k >= 0 && (n_main != end_k + 1 || end_k + 1 >= (long long)n))) {
        PyErr_SetString(PyExc_ValueError, "n_main, end_k: outside the pattern");
        return NULL;
    }
    /* memory safety: each breakpoint reads within the reaches it is limited by, on the
     * direction's side */
    for (npy_intp e = 0; e < n; e++) {
        if (sx * lerp.dxa[e] < 0 || sx * lerp.dxb[e] < 0 || sy * lerp.dya[e] < 0 ||
            sy * lerp.dyb[e] < 0 || sx * lerp.dxa[e] > rx[e] || sx * lerp.dxb[e] > rx[e] ||
            sy * lerp.dya[e] > ry[e] || sy * lerp.dyb[e] > ry[e] ||
            (e && (rx[e] < rx[e - 1] || ry[e] < ry[e - 1]))) {
            PyErr_Format(PyExc_ValueError, "pattern: breakpoint %ld reads outside its reach",
                         (long)e);
            return NULL;
        }
    }
    if (!lerp_offsets(&lerp, n, f.cols, &off_a, &off_b)) return NULL;
    hf_timed_begin(&section);
    hf_horizon_rows(f.H, f.rows, f.cols, n, inv_t, off_a, off_b, lerp.w, rx, ry, sx, sy, n_main,
                    end_k, end_f, end_inv_t, row_start, row_stop, (double *)out);
    elapsed_ns = hf_timed_end(&section);
    free(off_a);
    free(off_b);
    return stats_tuple(&st, elapsed_ns);
}

/* A unit direction (the strips' coordinates assume |d| = 1, to far below their slack). */
static int check_unit_direction(double dx, double dy) {
    if (!isfinite(dx) || !isfinite(dy) || !(fabs(dx * dx + dy * dy - 1.0) <= 1e-12)) {
        PyErr_SetString(PyExc_ValueError, "direction: expected a finite unit vector (dx, dy)");
        return 0;
    }
    return 1;
}

/* A power of two in [2^-20, 2^20] (a bin length: its inverse is exact). */
static int is_power_of_two(double v) {
    int e;
    return isfinite(v) && v >= 0x1p-20 && v <= 0x1p20 && frexp(v, &e) == 0.5;
}

/* The strips of one direction: (data, offset, n_bins, width, bin), checked against the
 * frame hf_horizon_strips_frame gives for this grid, so that every index the walk and the
 * build form lies inside data. */
static int get_strips(PyObject *o_strips, int64_t rows, int64_t cols, double dx, double dy,
                      int writable, hf_hz_strips *s, float **data_w) {
    PyObject *o_data, *o_off, *o_bins;
    npy_intp n_data, n_levels;
    int64_t n_bins0;
    void *p;
    if (!PyTuple_Check(o_strips)) {
        PyErr_SetString(PyExc_TypeError,
                        "strips: expected the tuple (data, offset, n_bins, width, bin)");
        return 0;
    }
    if (!PyArg_ParseTuple(o_strips, "OOOdd", &o_data, &o_off, &o_bins, &s->width, &s->bin))
        return 0;
    if (!(isfinite(s->width) && s->width > 0 && is_power_of_two(s->bin)) ||
        hf_horizon_strips_frame(rows, cols, dx, dy, s->width, s->bin, &s->c_min, &s->a_min,
                                &s->n_strips, &n_bins0) != 0) {
        PyErr_SetString(PyExc_ValueError, "strips: width must be positive and bin a power of "
                                          "two, and the strips of this grid must fit in int64");
        return 0;
    }
    s->inv_bin = 1.0 / s->bin;
    if (!hf_arg_array(o_data, "strips data", NPY_FLOAT32, -1, writable, 0, &p, &n_data)) return 0;
    s->data = (const float *)p;
    *data_w = (float *)p;
    if (!hf_arg_array(o_off, "strips offset", NPY_INT64, -1, 0, 0, &p, &n_levels)) return 0;
    s->offset = (const int64_t *)p;
    if (!hf_arg_array(o_bins, "strips n_bins", NPY_INT64, n_levels, 0, 0, &p, NULL)) return 0;
    s->n_bins = (const int64_t *)p;
    if (n_levels < 1 || n_levels > 62) {
        PyErr_SetString(PyExc_ValueError, "strips: 1 to 62 levels");
        return 0;
    }
    for (npy_intp l = 0; l < n_levels; l++) {
        int64_t want_bins = l ? (s->n_bins[l - 1] + 1) / 2 : n_bins0;
        int64_t want_off = l ? s->offset[l - 1] + s->n_strips * s->n_bins[l - 1] : 0;
        if (s->n_bins[l] != want_bins || s->offset[l] != want_off ||
            (l + 1 == n_levels) != (want_bins == 1)) {
            PyErr_Format(PyExc_ValueError,
                         "strips: level %ld does not match the grid's frame "
                         "(%lld strips, %lld bins at level 0)",
                         (long)l, (long long)s->n_strips, (long long)n_bins0);
            return 0;
        }
    }
    if (s->offset[n_levels - 1] + s->n_strips != n_data) {
        PyErr_Format(PyExc_ValueError, "strips data: expected %lld values, got %ld",
                     (long long)(s->offset[n_levels - 1] + s->n_strips), (long)n_data);
        return 0;
    }
    s->n_levels = (int32_t)n_levels;
    return 1;
}

PyDoc_STRVAR(horizon_strips_frame_doc,
             "horizon_strips_frame(rows, cols, dx, dy, width, bin)\n"
             "-> (c_min, a_min, n_strips, n_bins0)\n\n"
             "The frame of the chain walk's strips for a grid and a unit direction.\n"
             "Private: use algos.horizon.");

static PyObject *horizon_strips_frame(PyObject *self, PyObject *args) {
    long long rows, cols;
    double dx, dy, width, bin, c_min, a_min;
    int64_t n_strips, n_bins0;
    (void)self;
    if (!PyArg_ParseTuple(args, "LLdddd", &rows, &cols, &dx, &dy, &width, &bin)) return NULL;
    if (rows < 2 || cols < 2 || rows > ((long long)1 << 24) || cols > ((long long)1 << 24)) {
        PyErr_SetString(PyExc_ValueError, "rows, cols: each in [2, 2^24]");
        return NULL;
    }
    if (!check_unit_direction(dx, dy)) return NULL;
    if (!(isfinite(width) && width > 0 && is_power_of_two(bin)) ||
        hf_horizon_strips_frame(rows, cols, dx, dy, width, bin, &c_min, &a_min, &n_strips,
                                &n_bins0) != 0) {
        PyErr_SetString(PyExc_ValueError, "width, bin: width positive, bin a power of two in "
                                          "[2^-20, 2^20], with a frame that fits in int64");
        return NULL;
    }
    return Py_BuildValue("ddLL", c_min, a_min, (long long)n_strips, (long long)n_bins0);
}

PyDoc_STRVAR(horizon_strips_doc,
             "horizon_strips(heights, strips, dx, dy) -> ns\n\n"
             "Fill the chain walk's strips (data, offset, n_bins, width, bin) of a unit\n"
             "direction. Private: use algos.horizon.");

static PyObject *horizon_strips(PyObject *self, PyObject *args) {
    PyObject *o_h, *o_strips;
    double dx, dy;
    float *data;
    hf_hz_strips s;
    hf_timed_section section;
    long long elapsed_ns;
    terrain_field f;
    (void)self;
    if (!PyArg_ParseTuple(args, "OOdd", &o_h, &o_strips, &dx, &dy)) return NULL;
    if (!get_field(o_h, 0, 0, 0, NULL, &f)) return NULL;
    if (!check_unit_direction(dx, dy)) return NULL;
    if (!get_strips(o_strips, f.rows, f.cols, dx, dy, 1, &s, &data)) return NULL;
    hf_timed_begin(&section);
    hf_horizon_strips_build(f.H, f.rows, f.cols, dx, dy, &s, data);
    elapsed_ns = hf_timed_end(&section);
    return PyLong_FromLongLong(elapsed_ns);
}

PyDoc_STRVAR(horizon_chain_doc,
             "horizon_chain(heights, strips, dx, dy, max_distance, nb_x, nb_y, nb_d, block_rows,\n"
             "              block_start, block_stop, out, occ)\n"
             "-> (ns, cells, skips, tile_tests, bounded, cell_skips)\n\n"
             "Per-vertex walks that skip along the direction's strips (horizon_strips),\n"
             "started from lower bounds borrowed along almost the same line. Private: use\n"
             "algos.horizon.");

static PyObject *horizon_chain(PyObject *self, PyObject *args) {
    PyObject *o_h, *o_strips, *o_nx, *o_ny, *o_nd, *o_out, *o_occ;
    double dx, dy, max_distance;
    float *unused;
    long long block_rows, block_start, block_stop;
    const double *nb_d;
    const int64_t *nb_x, *nb_y;
    int64_t n_blocks;
    npy_intp n_nb;
    void *p, *out, *occ;
    hf_chain_stats st = {0, 0, 0, 0, 0};
    hf_hz_strips strips;
    hf_timed_section section;
    long long elapsed_ns;
    terrain_field f;
    (void)self;
    if (!PyArg_ParseTuple(args, "OOdddOOOLLLOO", &o_h, &o_strips, &dx, &dy, &max_distance, &o_nx,
                          &o_ny, &o_nd, &block_rows, &block_start, &block_stop, &o_out, &o_occ))
        return NULL;
    if (!get_field(o_h, 0, 0, 0, NULL, &f)) return NULL;
    if (!check_direction(dx, dy, max_distance) || !check_unit_direction(dx, dy)) return NULL;
    if (!get_strips(o_strips, f.rows, f.cols, dx, dy, 0, &strips, &unused)) return NULL;
    if (block_rows < 1) {
        PyErr_SetString(PyExc_ValueError, "block_rows: expected >= 1");
        return NULL;
    }
    n_blocks = (f.rows + block_rows - 1) / block_rows;
    if (block_start < 0 || block_stop < block_start || block_stop > n_blocks) {
        PyErr_Format(PyExc_ValueError, "block range [%lld, %lld) outside [0, %lld]", block_start,
                     block_stop, (long long)n_blocks);
        return NULL;
    }
    if (!hf_arg_array(o_nx, "nb_x", NPY_INT64, -1, 0, 0, &p, &n_nb)) return NULL;
    nb_x = (const int64_t *)p;
    if (!hf_arg_array(o_ny, "nb_y", NPY_INT64, n_nb, 0, 0, &p, NULL)) return NULL;
    nb_y = (const int64_t *)p;
    if (!hf_arg_array(o_nd, "nb_d", NPY_FLOAT64, n_nb, 0, 0, &p, NULL)) return NULL;
    nb_d = (const double *)p;
    for (npy_intp k = 0; k < n_nb; k++) {
        /* any vertex serves (the bound is a point of v's own ray); ahead is merely useful.
         * (0, 0) with nb_d = 0 reads v's own occ as it is on entry (NaN: no bound), the
         * oracle of bench/studies/horizon_oracle.py */
        const int self = nb_x[k] == 0 && nb_y[k] == 0;
        if (!isfinite(nb_d[k]) || (self ? nb_d[k] != 0.0 : !(nb_d[k] > 0.0))) {
            PyErr_Format(PyExc_ValueError,
                         "neighbour %ld: expected an offset ahead (nb_d > 0), or (0, 0) with "
                         "nb_d = 0",
                         (long)k);
            return NULL;
        }
    }
    if (!get_vertex_out(o_out, "out", &f, NPY_FLOAT64, &out)) return NULL;
    if (!get_vertex_out(o_occ, "occ", &f, NPY_FLOAT64, &occ)) return NULL;
    hf_timed_begin(&section);
    hf_horizon_chain(f.H, f.rows, f.cols, &strips, dx, dy, max_distance, n_nb, nb_x, nb_y, nb_d,
                     block_rows, block_start, block_stop, (double *)out, (double *)occ, &st);
    elapsed_ns = hf_timed_end(&section);
    return Py_BuildValue("LLLLLL", elapsed_ns, (long long)st.cells, (long long)st.skips,
                         (long long)st.tile_tests, (long long)st.bounded, (long long)st.cell_skips);
}

PyDoc_STRVAR(viewshed_doc,
             "viewshed(heights, mip, ox, oy, z0, target_height, drop, eps, start, stop, out)\n"
             "-> (ns, cells, skips)\n\nLine of sight to every target vertex: out 0 visible,\n"
             "1 blocked, 2 uncertain. Private: use algos.viewshed.");

static PyObject *viewshed(PyObject *self, PyObject *args) {
    PyObject *o_h, *o_mip, *o_out;
    double ox, oy, z0, th, drop, eps;
    long long start, stop;
    void *out;
    hf_hz_stats st = {0, 0};
    hf_timed_section section;
    long long elapsed_ns;
    terrain_field f;
    (void)self;
    if (!PyArg_ParseTuple(args, "OOddddddLLO", &o_h, &o_mip, &ox, &oy, &z0, &th, &drop, &eps,
                          &start, &stop, &o_out))
        return NULL;
    if (!get_field(o_h, 1, start, stop, o_mip, &f)) return NULL;
    if (!check_observer(&f, ox, oy, z0, th, drop, !(eps >= 0) || !isfinite(eps))) return NULL;
    if (!get_vertex_out(o_out, "out", &f, NPY_UINT8, &out)) return NULL;
    hf_timed_begin(&section);
    hf_viewshed(f.H, f.rows, f.cols, mip_of(&f), ox, oy, z0, th, drop, eps, start, stop,
                (uint8_t *)out, &st);
    elapsed_ns = hf_timed_end(&section);
    return stats_tuple(&st, elapsed_ns);
}

PyDoc_STRVAR(
    viewshed_threshold_doc,
    "viewshed_threshold(heights, mip, ox, oy, z0, target_height, drop, kind, start, stop,\n"
    "out) -> (ns, cells, skips)\n\nThe bound on the target top (kind 0) or the eye "
    "(kind 1)\nthat a line of sight to every target vertex needs: float64 out, -inf "
    "where\nnothing lies between. Private: use algos.viewshed(mode=...).");

static PyObject *viewshed_threshold(PyObject *self, PyObject *args) {
    PyObject *o_h, *o_mip, *o_out;
    double ox, oy, z0, th, drop;
    int kind;
    long long start, stop;
    void *out;
    hf_hz_stats st = {0, 0};
    hf_timed_section section;
    long long elapsed_ns;
    terrain_field f;
    (void)self;
    if (!PyArg_ParseTuple(args, "OOdddddiLLO", &o_h, &o_mip, &ox, &oy, &z0, &th, &drop, &kind,
                          &start, &stop, &o_out))
        return NULL;
    if (!get_field(o_h, 1, start, stop, o_mip, &f)) return NULL;
    if (!check_observer(&f, ox, oy, z0, th, drop, 0)) return NULL;
    if (kind != HF_VS_TARGET && kind != HF_VS_OBSERVER) {
        PyErr_Format(PyExc_ValueError, "kind: expected 0 (target) or 1 (observer), got %d", kind);
        return NULL;
    }
    if (!get_vertex_out(o_out, "out", &f, NPY_FLOAT64, &out)) return NULL;
    hf_timed_begin(&section);
    hf_viewshed_threshold(f.H, f.rows, f.cols, mip_of(&f), ox, oy, z0, th, drop, kind, start, stop,
                          (double *)out, &st);
    elapsed_ns = hf_timed_end(&section);
    return stats_tuple(&st, elapsed_ns);
}

PyDoc_STRVAR(horizon_march_doc,
             "horizon_march(heights, dx, dy, step, max_distance, zmax, start, stop, out,\n"
             "              kappa=0.0) -> (ns, samples, 0)\n\nThe r.horizon-style fixed-step\n"
             "marcher; kappa: curvature. Private: use algos.horizon(algorithm='march').");

static PyObject *horizon_march(PyObject *self, PyObject *args) {
    PyObject *o_h, *o_out;
    double dx, dy, step, max_distance, zmax, kappa = 0.0;
    long long start, stop;
    void *out;
    hf_hz_stats st = {0, 0};
    hf_timed_section section;
    long long elapsed_ns;
    terrain_field f;
    (void)self;
    if (!PyArg_ParseTuple(args, "OdddddLLO|d", &o_h, &dx, &dy, &step, &max_distance, &zmax, &start,
                          &stop, &o_out, &kappa))
        return NULL;
    if (!check_kappa(kappa)) return NULL;
    if (!get_field(o_h, 1, start, stop, NULL, &f)) return NULL;
    if (!isfinite(dx) || !isfinite(dy) || (dx == 0 && dy == 0) || !(step > 0) || !isfinite(step) ||
        isnan(max_distance) || isnan(zmax)) {
        PyErr_SetString(PyExc_ValueError, "direction, step or max_distance invalid");
        return NULL;
    }
    if (!get_vertex_out(o_out, "out", &f, NPY_FLOAT64, &out)) return NULL;
    hf_timed_begin(&section);
    hf_horizon_march(f.H, f.rows, f.cols, dx, dy, step, max_distance, zmax, kappa, start, stop,
                     (double *)out, &st);
    elapsed_ns = hf_timed_end(&section);
    return stats_tuple(&st, elapsed_ns);
}

static PyMethodDef terrain_methods[] = {
    {"horizon_pattern", horizon_pattern, METH_VARARGS, horizon_pattern_doc},
    {"horizon_sweep", horizon_sweep, METH_VARARGS, horizon_sweep_doc},
    {"horizon_walk", horizon_walk, METH_VARARGS, horizon_walk_doc},
    {"horizon_rows", horizon_rows, METH_VARARGS, horizon_rows_doc},
    {"horizon_chain", horizon_chain, METH_VARARGS, horizon_chain_doc},
    {"horizon_strips_frame", horizon_strips_frame, METH_VARARGS, horizon_strips_frame_doc},
    {"horizon_strips", horizon_strips, METH_VARARGS, horizon_strips_doc},
    {"viewshed", viewshed, METH_VARARGS, viewshed_doc},
    {"viewshed_threshold", viewshed_threshold, METH_VARARGS, viewshed_threshold_doc},
    {"horizon_march", horizon_march, METH_VARARGS, horizon_march_doc},
    {NULL, NULL, 0, NULL}};

int hf_bind_terrain(PyObject *module) {
    return PyModule_AddFunctions(module, terrain_methods);
}
