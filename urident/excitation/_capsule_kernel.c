/*
 * Compiled kernel of urident.excitation.collision.CapsuleModel.distances and .distance_derivatives:
 * the same joint-frame kinematics and closest points of two segments (Ericson, Real-Time Collision
 * Detection, 5.1.9, with the degenerate cases) as the numpy implementation, one sample at a time,
 * written into the caller's output. Plain CPython with the buffer protocol: no numpy headers needed.
 *
 * geometry: 6 joints x (xyz[3], R0[9] row-major) doubles (the regressor kernel's packing).
 * axes: 6 bytes, 0 = x, 1 = y, 2 = z.
 * capsules: C x (frame, a[3], b[3], radius) doubles; frame -1 is the base.
 * pairs: P x 2 int32 capsule indices; floor: F int32 capsule indices.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>

#define NJ 6
#define EPS 1e-12
#define MAX_CAPSULES 64

static inline double clip01(double v) { return v < 0.0 ? 0.0 : (v > 1.0 ? 1.0 : v); }

static inline double dot3(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

/* Frame rotations (row-major) and origins of K_0 (the base) .. K_6 for one sample. */
static void frames(const double *geom, const unsigned char *axes, const double *q, double rot[NJ + 1][9],
                   double pos[NJ + 1][3]) {
    static const double eye[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    for (int m = 0; m < 9; m++) rot[0][m] = eye[m];
    pos[0][0] = pos[0][1] = pos[0][2] = 0.0;
    for (int i = 0; i < NJ; i++) {
        const double *xyz = geom + 12 * i, *r0 = geom + 12 * i + 3, *rp = rot[i];
        double m[9];
        for (int r = 0; r < 3; r++) {
            pos[i + 1][r] = pos[i][r] + rp[3 * r] * xyz[0] + rp[3 * r + 1] * xyz[1] + rp[3 * r + 2] * xyz[2];
            for (int col = 0; col < 3; col++)
                m[3 * r + col] = rp[3 * r] * r0[col] + rp[3 * r + 1] * r0[3 + col] + rp[3 * r + 2] * r0[6 + col];
        }
        int ax = axes[i], j = (ax + 1) % 3, k = (ax + 2) % 3;
        double c = cos(q[i]), s = sin(q[i]);
        double *out = rot[i + 1];
        for (int r = 0; r < 3; r++) {
            out[3 * r + ax] = m[3 * r + ax];
            out[3 * r + j] = c * m[3 * r + j] + s * m[3 * r + k];
            out[3 * r + k] = -s * m[3 * r + j] + c * m[3 * r + k];
        }
    }
}

/* Parameters s, t in [0, 1] of the closest points p1 + s(q1 - p1) and p2 + t(q2 - p2). */
static void segment_closest(const double *p1, const double *q1, const double *p2, const double *q2, double *s_out,
                            double *t_out) {
    double d1[3], d2[3], r[3];
    for (int m = 0; m < 3; m++) { d1[m] = q1[m] - p1[m]; d2[m] = q2[m] - p2[m]; r[m] = p1[m] - p2[m]; }
    double a = dot3(d1, d1), e = dot3(d2, d2), f = dot3(d2, r), c = dot3(d1, r), b = dot3(d1, d2);
    int a_ok = a > EPS, e_ok = e > EPS;
    double safe_a = a_ok ? a : 1.0, safe_e = e_ok ? e : 1.0;
    double denom = a * e - b * b, ae = a * e > EPS ? a * e : EPS;
    double s = denom > EPS * ae ? clip01((b * f - c * e) / (denom > 0 ? denom : 1.0)) : 0.0;
    double t = (b * s + f) / safe_e;
    if (t < 0) s = clip01(-c / safe_a);
    else if (t > 1) s = clip01((b - c) / safe_a);
    t = clip01(t);
    if (!a_ok) { s = 0.0; t = clip01(f / safe_e); }
    if (a_ok && !e_ok) s = clip01(-c / safe_a);
    if (!e_ok) t = 0.0;
    *s_out = s; *t_out = t;
}

/* The closest points c1, c2 of two segments; returns their distance. */
static double closest_points(const double *p1, const double *q1, const double *p2, const double *q2, double *c1,
                             double *c2) {
    double s, t, diff[3];
    segment_closest(p1, q1, p2, q2, &s, &t);
    for (int m = 0; m < 3; m++) {
        c1[m] = p1[m] + (q1[m] - p1[m]) * s;
        c2[m] = p2[m] + (q2[m] - p2[m]) * t;
        diff[m] = c1[m] - c2[m];
    }
    return sqrt(dot3(diff, diff));
}

static double segment_distance(const double *p1, const double *q1, const double *p2, const double *q2) {
    double c1[3], c2[3];
    return closest_points(p1, q1, p2, q2, c1, c2);
}

/* Every capsule's segment end points in the base frame, for one sample's frames. */
static void capsule_ends(const double *pc, Py_ssize_t nc, double rot[NJ + 1][9], double pos[NJ + 1][3],
                         double ends[MAX_CAPSULES][2][3]) {
    for (Py_ssize_t c = 0; c < nc; c++) {
        const double *cap = pc + 8 * c;
        int f = (int)cap[0] + 1;
        for (int end = 0; end < 2; end++) {
            const double *v = cap + 1 + 3 * end;
            for (int r = 0; r < 3; r++)
                ends[c][end][r] = rot[f][3 * r] * v[0] + rot[f][3 * r + 1] * v[1] + rot[f][3 * r + 2] * v[2]
                                  + pos[f][r];
        }
    }
}

/* The velocity of world point x per unit rate of each joint j carrying a capsule on frame `frame`:
 * z_j x (x - o_j), zero for joints after it. */
static void point_jacobian(const unsigned char *axes, double rot[NJ + 1][9], double pos[NJ + 1][3], int frame,
                           const double *x, double v[NJ][3]) {
    for (int j = 0; j < NJ; j++) {
        if (frame < j) { v[j][0] = v[j][1] = v[j][2] = 0.0; continue; }
        int ax = axes[j];
        double z[3] = {rot[j + 1][ax], rot[j + 1][3 + ax], rot[j + 1][6 + ax]};
        double d[3] = {x[0] - pos[j + 1][0], x[1] - pos[j + 1][1], x[2] - pos[j + 1][2]};
        v[j][0] = z[1] * d[2] - z[2] * d[1];
        v[j][1] = z[2] * d[0] - z[0] * d[2];
        v[j][2] = z[0] * d[1] - z[1] * d[0];
    }
}

/* The sizes of a call's robot and capsule buffers (n samples, nc capsules, np_ pairs, nf floor
 * capsules); 0 if they are inconsistent or an index is out of range. */
static int model_sizes(const Py_buffer *q, const Py_buffer *geom, const Py_buffer *axes, const Py_buffer *caps,
                       const Py_buffer *pairs, const Py_buffer *floor_caps, Py_ssize_t *n, Py_ssize_t *nc,
                       Py_ssize_t *np_, Py_ssize_t *nf) {
    *n = q->len / (Py_ssize_t)(sizeof(double) * NJ);
    *nc = caps->len / (Py_ssize_t)(sizeof(double) * 8);
    *np_ = pairs->len / (Py_ssize_t)(sizeof(int32_t) * 2);
    *nf = floor_caps->len / (Py_ssize_t)sizeof(int32_t);
    int ok = q->len == *n * (Py_ssize_t)(sizeof(double) * NJ) && *nc <= MAX_CAPSULES
          && caps->len == *nc * (Py_ssize_t)(sizeof(double) * 8)
          && geom->len == (Py_ssize_t)(sizeof(double) * 12 * NJ) && axes->len == NJ;
    const double *pc = caps->buf;
    const int32_t *pp = pairs->buf, *pf = floor_caps->buf;
    for (Py_ssize_t c = 0; ok && c < *nc; c++) ok = pc[8 * c] >= -1 && pc[8 * c] < NJ;
    for (Py_ssize_t m = 0; ok && m < 2 * *np_; m++) ok = pp[m] >= 0 && pp[m] < *nc;
    for (Py_ssize_t m = 0; ok && m < *nf; m++) ok = pf[m] >= 0 && pf[m] < *nc;
    return ok;
}

static PyObject *distances(PyObject *self, PyObject *args) {
    Py_buffer out, q, geom, axes, caps, pairs, floor_caps;
    double floor_height;
    if (!PyArg_ParseTuple(args, "w*y*y*y*y*y*y*d", &out, &q, &geom, &axes, &caps, &pairs, &floor_caps,
                          &floor_height)) {
        return NULL;
    }
    Py_ssize_t n, nc, np_, nf;
    int ok = model_sizes(&q, &geom, &axes, &caps, &pairs, &floor_caps, &n, &nc, &np_, &nf)
          && out.len == n * (np_ + nf) * (Py_ssize_t)sizeof(double);
    const double *pc = caps.buf;
    const int32_t *pp = pairs.buf, *pf = floor_caps.buf;
    if (ok) {
        const double *pq = q.buf;
        double *po = out.buf;
        Py_BEGIN_ALLOW_THREADS
        double rot[NJ + 1][9], pos[NJ + 1][3], ends[MAX_CAPSULES][2][3];
        for (Py_ssize_t k = 0; k < n; k++) {
            frames(geom.buf, axes.buf, pq + NJ * k, rot, pos);
            capsule_ends(pc, nc, rot, pos, ends);
            double *row = po + (np_ + nf) * k;
            for (Py_ssize_t m = 0; m < np_; m++) {
                int c1 = pp[2 * m], c2 = pp[2 * m + 1];
                row[m] = segment_distance(ends[c1][0], ends[c1][1], ends[c2][0], ends[c2][1])
                         - pc[8 * c1 + 7] - pc[8 * c2 + 7];
            }
            for (Py_ssize_t m = 0; m < nf; m++) {
                int c = pf[m];
                double low = ends[c][0][2] < ends[c][1][2] ? ends[c][0][2] : ends[c][1][2];
                row[np_ + m] = low - pc[8 * c + 7] - floor_height;
            }
        }
        Py_END_ALLOW_THREADS
    }
    PyBuffer_Release(&out); PyBuffer_Release(&q); PyBuffer_Release(&geom); PyBuffer_Release(&axes);
    PyBuffer_Release(&caps); PyBuffer_Release(&pairs); PyBuffer_Release(&floor_caps);
    if (!ok) {
        PyErr_SetString(PyExc_ValueError, "capsule kernel: inconsistent buffer sizes or indices");
        return NULL;
    }
    Py_RETURN_NONE;
}

/* The distances' derivatives in the joint angles at the entries `where` is nonzero, zero elsewhere:
 * the unit normal between the closest points times their velocities (their own motion along the
 * segments does not change the distance to first order); zero where two segments touch. */
static PyObject *derivatives(PyObject *self, PyObject *args) {
    Py_buffer out, q, geom, axes, caps, pairs, floor_caps, where;
    if (!PyArg_ParseTuple(args, "w*y*y*y*y*y*y*y*", &out, &q, &geom, &axes, &caps, &pairs, &floor_caps, &where)) {
        return NULL;
    }
    Py_ssize_t n, nc, np_, nf;
    int ok = model_sizes(&q, &geom, &axes, &caps, &pairs, &floor_caps, &n, &nc, &np_, &nf)
          && out.len == n * (np_ + nf) * (Py_ssize_t)(sizeof(double) * NJ) && where.len == n * (np_ + nf);
    const double *pc = caps.buf;
    const int32_t *pp = pairs.buf, *pf = floor_caps.buf;
    if (ok) {
        const double *pq = q.buf;
        const unsigned char *pw = where.buf, *ax = axes.buf;
        double *po = out.buf;
        Py_BEGIN_ALLOW_THREADS
        double rot[NJ + 1][9], pos[NJ + 1][3], ends[MAX_CAPSULES][2][3], v1[NJ][3], v2[NJ][3];
        for (Py_ssize_t k = 0; k < n; k++) {
            const unsigned char *wrow = pw + (np_ + nf) * k;
            double *row = po + (np_ + nf) * NJ * k;
            int any = 0;
            for (Py_ssize_t m = 0; m < np_ + nf; m++) any |= wrow[m];
            for (Py_ssize_t m = 0; m < (np_ + nf) * NJ; m++) row[m] = 0.0;
            if (!any) continue;
            frames(geom.buf, ax, pq + NJ * k, rot, pos);
            capsule_ends(pc, nc, rot, pos, ends);
            for (Py_ssize_t m = 0; m < np_; m++) {
                if (!wrow[m]) continue;
                int k1 = pp[2 * m], k2 = pp[2 * m + 1];
                double c1[3], c2[3], normal[3];
                double gap = closest_points(ends[k1][0], ends[k1][1], ends[k2][0], ends[k2][1], c1, c2);
                if (!(gap > EPS)) continue;
                for (int r = 0; r < 3; r++) normal[r] = (c1[r] - c2[r]) / gap;
                point_jacobian(ax, rot, pos, (int)pc[8 * k1], c1, v1);
                point_jacobian(ax, rot, pos, (int)pc[8 * k2], c2, v2);
                for (int j = 0; j < NJ; j++)
                    row[NJ * m + j] = normal[0] * (v1[j][0] - v2[j][0]) + normal[1] * (v1[j][1] - v2[j][1])
                                      + normal[2] * (v1[j][2] - v2[j][2]);
            }
            for (Py_ssize_t m = 0; m < nf; m++) {
                if (!wrow[np_ + m]) continue;
                int c = pf[m];
                const double *low = ends[c][0][2] <= ends[c][1][2] ? ends[c][0] : ends[c][1];
                point_jacobian(ax, rot, pos, (int)pc[8 * c], low, v1);
                for (int j = 0; j < NJ; j++) row[NJ * (np_ + m) + j] = v1[j][2];
            }
        }
        Py_END_ALLOW_THREADS
    }
    PyBuffer_Release(&out); PyBuffer_Release(&q); PyBuffer_Release(&geom); PyBuffer_Release(&axes);
    PyBuffer_Release(&caps); PyBuffer_Release(&pairs); PyBuffer_Release(&floor_caps); PyBuffer_Release(&where);
    if (!ok) {
        PyErr_SetString(PyExc_ValueError, "capsule kernel: inconsistent buffer sizes or indices");
        return NULL;
    }
    Py_RETURN_NONE;
}

static PyMethodDef methods[] = {
    {"distances", distances, METH_VARARGS,
     "distances(out, q, geometry, axes, capsules, pairs, floor, floor_height): write the (N, P + F) distances."},
    {"derivatives", derivatives, METH_VARARGS,
     "derivatives(out, q, geometry, axes, capsules, pairs, floor, where): write the (N, P + F, 6) derivatives "
     "of the distances in q where `where` (N, P + F, uint8) is nonzero, zero elsewhere."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_capsule_kernel", NULL, -1, methods};

PyMODINIT_FUNC PyInit__capsule_kernel(void) { return PyModule_Create(&module); }
