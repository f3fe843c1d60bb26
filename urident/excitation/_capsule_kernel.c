/*
 * Compiled kernel of urident.excitation.collision.CapsuleModel.distances: the same joint-frame
 * kinematics and closest points of two segments (Ericson, Real-Time Collision Detection, 5.1.9,
 * with the degenerate cases) as the numpy implementation, one sample at a time, written into the
 * caller's (N, P + F) output. Plain CPython with the buffer protocol: no numpy headers needed.
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

static double segment_distance(const double *p1, const double *q1, const double *p2, const double *q2) {
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
    double diff[3];
    for (int m = 0; m < 3; m++) diff[m] = (p1[m] + d1[m] * s) - (p2[m] + d2[m] * t);
    return sqrt(dot3(diff, diff));
}

static PyObject *distances(PyObject *self, PyObject *args) {
    Py_buffer out, q, geom, axes, caps, pairs, floor_caps;
    double floor_height;
    if (!PyArg_ParseTuple(args, "w*y*y*y*y*y*y*d", &out, &q, &geom, &axes, &caps, &pairs, &floor_caps,
                          &floor_height)) {
        return NULL;
    }
    Py_ssize_t n = q.len / (Py_ssize_t)(sizeof(double) * NJ);
    Py_ssize_t nc = caps.len / (Py_ssize_t)(sizeof(double) * 8);
    Py_ssize_t np_ = pairs.len / (Py_ssize_t)(sizeof(int32_t) * 2);
    Py_ssize_t nf = floor_caps.len / (Py_ssize_t)sizeof(int32_t);
    int ok = q.len == n * (Py_ssize_t)(sizeof(double) * NJ) && nc <= MAX_CAPSULES
          && caps.len == nc * (Py_ssize_t)(sizeof(double) * 8)
          && out.len == n * (np_ + nf) * (Py_ssize_t)sizeof(double)
          && geom.len == (Py_ssize_t)(sizeof(double) * 12 * NJ) && axes.len == NJ;
    const double *pc = caps.buf;
    const int32_t *pp = pairs.buf, *pf = floor_caps.buf;
    for (Py_ssize_t c = 0; ok && c < nc; c++) ok = pc[8 * c] >= -1 && pc[8 * c] < NJ;
    for (Py_ssize_t m = 0; ok && m < 2 * np_; m++) ok = pp[m] >= 0 && pp[m] < nc;
    for (Py_ssize_t m = 0; ok && m < nf; m++) ok = pf[m] >= 0 && pf[m] < nc;
    if (ok) {
        const double *pq = q.buf;
        double *po = out.buf;
        Py_BEGIN_ALLOW_THREADS
        double rot[NJ + 1][9], pos[NJ + 1][3], ends[MAX_CAPSULES][2][3];
        for (Py_ssize_t k = 0; k < n; k++) {
            frames(geom.buf, axes.buf, pq + NJ * k, rot, pos);
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

static PyMethodDef methods[] = {
    {"distances", distances, METH_VARARGS,
     "distances(out, q, geometry, axes, capsules, pairs, floor, floor_height): write the (N, P + F) distances."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_capsule_kernel", NULL, -1, methods};

PyMODINIT_FUNC PyInit__capsule_kernel(void) { return PyModule_Create(&module); }
