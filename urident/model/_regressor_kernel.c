/*
 * Compiled kernel of urident.model.regressor: the same recursion as the numpy implementation
 * (see regressor.py for the method), one sample at a time, written straight into the caller's
 * (N, 6, 78) output. Plain CPython with the buffer protocol: no numpy headers needed.
 *
 * geometry: 6 joints x (xyz[3], R0[9] row-major) = 72 doubles, then gravity[3].
 * axes: 6 bytes, 0 = x, 1 = y, 2 = z.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <string.h>

#define NJ 6
#define NP 78

static inline void cross3(const double *a, const double *b, double *out) {
    double x = a[1] * b[2] - a[2] * b[1];
    double y = a[2] * b[0] - a[0] * b[2];
    double z = a[0] * b[1] - a[1] * b[0];
    out[0] = x; out[1] = y; out[2] = z;
}

/* out = Rot_axis(q)^T R0^T v; r0 == NULL stands for the identity (most UR joints). */
static inline void rot_t(const double *r0, int axis, double c, double s, const double *v, double *out) {
    double u0, u1, u2;
    if (r0) {
        u0 = r0[0] * v[0] + r0[3] * v[1] + r0[6] * v[2];
        u1 = r0[1] * v[0] + r0[4] * v[1] + r0[7] * v[2];
        u2 = r0[2] * v[0] + r0[5] * v[1] + r0[8] * v[2];
    } else {
        u0 = v[0]; u1 = v[1]; u2 = v[2];
    }
    if (axis == 2) {
        out[0] = c * u0 + s * u1; out[1] = c * u1 - s * u0; out[2] = u2;
    } else if (axis == 1) {
        out[0] = c * u0 - s * u2; out[1] = u1; out[2] = s * u0 + c * u2;
    } else {
        out[0] = u0; out[1] = c * u1 + s * u2; out[2] = c * u2 - s * u1;
    }
}

static void body_wrench(const double *w, const double *wd, const double *a, double y[6][10]) {
    double wx = w[0], wy = w[1], wz = w[2], dx = wd[0], dy = wd[1], dz = wd[2];
    double ax = a[0], ay = a[1], az = a[2];
    double wxx = wx * wx, wyy = wy * wy, wzz = wz * wz, wxy = wx * wy, wxz = wx * wz, wyz = wy * wz;
    memset(y, 0, sizeof(double) * 60);
    y[0][0] = ax; y[1][0] = ay; y[2][0] = az;
    y[0][1] = -wyy - wzz; y[0][2] = wxy - dz; y[0][3] = wxz + dy;
    y[1][1] = wxy + dz; y[1][2] = -wxx - wzz; y[1][3] = wyz - dx;
    y[2][1] = wxz - dy; y[2][2] = wyz + dx; y[2][3] = -wxx - wyy;
    y[3][2] = az; y[3][3] = -ay;
    y[4][1] = -az; y[4][3] = ax;
    y[5][1] = ay; y[5][2] = -ax;
    y[3][4] = dx; y[3][5] = -wyz; y[3][6] = wyz;
    y[3][7] = wzz - wyy; y[3][8] = -dz - wxy; y[3][9] = -dy + wxz;
    y[4][4] = wxz; y[4][5] = dy; y[4][6] = -wxz;
    y[4][7] = -dz + wxy; y[4][8] = wxx - wzz; y[4][9] = -dx - wyz;
    y[5][4] = -wxy; y[5][5] = wxy; y[5][6] = dz;
    y[5][7] = -dy - wxz; y[5][8] = -dx + wyz; y[5][9] = wyy - wxx;
}

static int is_identity(const double *r) {
    return r[0] == 1.0 && r[1] == 0.0 && r[2] == 0.0 && r[3] == 0.0 && r[4] == 1.0 && r[5] == 0.0
        && r[6] == 0.0 && r[7] == 0.0 && r[8] == 1.0;
}

static void fill_sample(const double *geom, const unsigned char *axes, const int *identity, double eps,
                        const double *q, const double *qd, const double *qdd, double *out) {
    double w[3] = {0, 0, 0}, wd[3] = {0, 0, 0}, a[3], tmp[3], t1[3], t2[3];
    double lin[NJ][3], ang[NJ][3], y[6][10];
    const double *gravity = geom + 12 * NJ;
    a[0] = -gravity[0]; a[1] = -gravity[1]; a[2] = -gravity[2];
    /* Entries no body reaches: row k holds bodies i >= k only, plus its own rotor/friction terms. */
    for (int k = 0; k < NJ; k++) {
        memset(out + k * NP, 0, sizeof(double) * 10 * k);
        memset(out + k * NP + 60, 0, sizeof(double) * 18);
    }
    for (int i = 0; i < NJ; i++) {
        const double *p = geom + 12 * i, *r0 = identity[i] ? NULL : geom + 12 * i + 3;
        int axis = axes[i];
        double c = cos(q[i]), s = sin(q[i]);
        cross3(wd, p, t1);
        cross3(w, p, t2);
        cross3(w, t2, tmp);
        tmp[0] += a[0] + t1[0]; tmp[1] += a[1] + t1[1]; tmp[2] += a[2] + t1[2];
        rot_t(r0, axis, c, s, tmp, a);
        rot_t(r0, axis, c, s, w, w);
        rot_t(r0, axis, c, s, wd, wd);
        double e[3] = {0, 0, 0};
        e[axis] = 1.0;
        cross3(w, e, tmp);
        wd[0] += tmp[0] * qd[i]; wd[1] += tmp[1] * qd[i]; wd[2] += tmp[2] * qd[i];
        wd[axis] += qdd[i];
        w[axis] += qd[i];
        for (int k = 0; k < i; k++) {
            cross3(ang[k], p, tmp);
            tmp[0] += lin[k][0]; tmp[1] += lin[k][1]; tmp[2] += lin[k][2];
            rot_t(r0, axis, c, s, tmp, lin[k]);
            rot_t(r0, axis, c, s, ang[k], ang[k]);
        }
        lin[i][0] = lin[i][1] = lin[i][2] = 0.0;
        ang[i][0] = e[0]; ang[i][1] = e[1]; ang[i][2] = e[2];
        body_wrench(w, wd, a, y);
        for (int k = 0; k <= i; k++) {
            double *row = out + k * NP + 10 * i;
            const double *v = lin[k], *u = ang[k];
            for (int col = 0; col < 10; col++) {
                row[col] = v[0] * y[0][col] + v[1] * y[1][col] + v[2] * y[2][col]
                         + u[0] * y[3][col] + u[1] * y[4][col] + u[2] * y[5][col];
            }
        }
    }
    for (int j = 0; j < NJ; j++) {
        out[j * NP + 60 + j] = qdd[j];
        out[j * NP + 66 + j] = qd[j];
        out[j * NP + 72 + j] = tanh(qd[j] / eps);
    }
}

static PyObject *fill(PyObject *self, PyObject *args) {
    Py_buffer out, q, qd, qdd, geom, axes;
    double eps;
    if (!PyArg_ParseTuple(args, "w*y*y*y*y*y*d", &out, &q, &qd, &qdd, &geom, &axes, &eps)) {
        return NULL;
    }
    Py_ssize_t n = q.len / (Py_ssize_t)(sizeof(double) * NJ);
    int ok = q.len == qd.len && q.len == qdd.len
          && out.len == n * (Py_ssize_t)(sizeof(double) * NJ * NP)
          && geom.len == (Py_ssize_t)(sizeof(double) * (12 * NJ + 3)) && axes.len == NJ;
    if (ok) {
        const double *pq = q.buf, *pqd = qd.buf, *pqdd = qdd.buf;
        double *po = out.buf;
        int identity[NJ];
        for (int i = 0; i < NJ; i++) identity[i] = is_identity((const double *)geom.buf + 12 * i + 3);
        Py_BEGIN_ALLOW_THREADS
        for (Py_ssize_t k = 0; k < n; k++) {
            fill_sample(geom.buf, axes.buf, identity, eps, pq + NJ * k, pqd + NJ * k, pqdd + NJ * k,
                        po + NJ * NP * k);
        }
        Py_END_ALLOW_THREADS
    }
    PyBuffer_Release(&out); PyBuffer_Release(&q); PyBuffer_Release(&qd); PyBuffer_Release(&qdd);
    PyBuffer_Release(&geom); PyBuffer_Release(&axes);
    if (!ok) {
        PyErr_SetString(PyExc_ValueError, "regressor kernel: inconsistent buffer sizes");
        return NULL;
    }
    Py_RETURN_NONE;
}

static PyMethodDef methods[] = {
    {"fill", fill, METH_VARARGS, "fill(out, q, qd, qdd, geometry, axes, eps): write the (N, 6, 78) regressor."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_regressor_kernel", NULL, -1, methods};

PyMODINIT_FUNC PyInit__regressor_kernel(void) { return PyModule_Create(&module); }
