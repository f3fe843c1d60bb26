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

/* The chain entering a joint: the parent's w, wd, origin acceleration, and lin/ang of the joints before. */
typedef struct {
    double w[3], wd[3], a[3], lin[NJ][3], ang[NJ][3];
} chain_state;

/* Across joint i: the origin's acceleration, w, wd and (with motion) lin/ang of joints k <= i, in K_i. */
static void advance(const double *geom, const unsigned char *axes, const int *identity, int i, double c,
                    double s, double qd, double qdd, chain_state *st, int motion) {
    const double *p = geom + 12 * i, *r0 = identity[i] ? NULL : geom + 12 * i + 3;
    int axis = axes[i];
    double tmp[3], t1[3], t2[3];
    cross3(st->wd, p, t1);
    cross3(st->w, p, t2);
    cross3(st->w, t2, tmp);
    tmp[0] += st->a[0] + t1[0]; tmp[1] += st->a[1] + t1[1]; tmp[2] += st->a[2] + t1[2];
    rot_t(r0, axis, c, s, tmp, st->a);
    rot_t(r0, axis, c, s, st->w, st->w);
    rot_t(r0, axis, c, s, st->wd, st->wd);
    double e[3] = {0, 0, 0};
    e[axis] = 1.0;
    cross3(st->w, e, tmp);
    st->wd[0] += tmp[0] * qd; st->wd[1] += tmp[1] * qd; st->wd[2] += tmp[2] * qd;
    st->wd[axis] += qdd;
    st->w[axis] += qd;
    if (!motion) return;
    for (int k = 0; k < i; k++) {
        cross3(st->ang[k], p, tmp);
        tmp[0] += st->lin[k][0]; tmp[1] += st->lin[k][1]; tmp[2] += st->lin[k][2];
        rot_t(r0, axis, c, s, tmp, st->lin[k]);
        rot_t(r0, axis, c, s, st->ang[k], st->ang[k]);
    }
    st->lin[i][0] = st->lin[i][1] = st->lin[i][2] = 0.0;
    st->ang[i][0] = e[0]; st->ang[i][1] = e[1]; st->ang[i][2] = e[2];
}

static void fill_sample(const double *geom, const unsigned char *axes, const int *identity, double eps,
                        const double *q, const double *qd, const double *qdd, double *out) {
    chain_state st;
    double y[6][10];
    const double *gravity = geom + 12 * NJ;
    memset(&st, 0, sizeof st);
    st.a[0] = -gravity[0]; st.a[1] = -gravity[1]; st.a[2] = -gravity[2];
    /* Entries no body reaches: row k holds bodies i >= k only, plus its own rotor/friction terms. */
    for (int k = 0; k < NJ; k++) {
        memset(out + k * NP, 0, sizeof(double) * 10 * k);
        memset(out + k * NP + 60, 0, sizeof(double) * 18);
    }
    for (int i = 0; i < NJ; i++) {
        advance(geom, axes, identity, i, cos(q[i]), sin(q[i]), qd[i], qdd[i], &st, 1);
        body_wrench(st.w, st.wd, st.a, y);
        for (int k = 0; k <= i; k++) {
            double *row = out + k * NP + 10 * i;
            const double *v = st.lin[k], *u = st.ang[k];
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

/* The state buffers' common checks: (N, 6) q, qd, qdd of one length, the geometry and axes of six
 * joints; sets *n and which joints' fixed rotations are the identity. */
static int chain_inputs(const Py_buffer *q, const Py_buffer *qd, const Py_buffer *qdd, const Py_buffer *geom,
                        const Py_buffer *axes, Py_ssize_t *n, int identity[NJ]) {
    *n = q->len / (Py_ssize_t)(sizeof(double) * NJ);
    if (q->len != qd->len || q->len != qdd->len || geom->len != (Py_ssize_t)(sizeof(double) * (12 * NJ + 3))
            || axes->len != NJ)
        return 0;
    for (int i = 0; i < NJ; i++) identity[i] = is_identity((const double *)geom->buf + 12 * i + 3);
    return 1;
}

static PyObject *fill(PyObject *self, PyObject *args) {
    Py_buffer out, q, qd, qdd, geom, axes;
    double eps;
    if (!PyArg_ParseTuple(args, "w*y*y*y*y*y*d", &out, &q, &qd, &qdd, &geom, &axes, &eps)) {
        return NULL;
    }
    Py_ssize_t n;
    int identity[NJ];
    int ok = chain_inputs(&q, &qd, &qdd, &geom, &axes, &n, identity)
          && out.len == n * (Py_ssize_t)(sizeof(double) * NJ * NP);
    if (ok) {
        const double *pq = q.buf, *pqd = qd.buf, *pqdd = qdd.buf;
        double *po = out.buf;
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

/* ---- derivatives of a weighted sum of one sample's regressor (the excitation gradient) ----
 * s = sum_{k,p} A[k][p] Theta[k][p]. Body i's columns give s_i = sum_{r,col} M_i[r][col] Y_i[r][col]
 * with M_i = sum_{k<=i} motion_k (x) A[k][10i..10i+9] (motion_k = [lin_k; ang_k] in K_i). A change of
 * q_j, qd_j or qdd_j leaves bodies i < j as they are, and one of qd_j or qdd_j leaves every motion_k
 * (so M_i) as it is: each derivative recomputes only bodies i >= j, from the chain entering joint j. */
static void weight_map(const chain_state *st, int i, const double *weights, double m[6][10]) {
    for (int r = 0; r < 6; r++)
        for (int col = 0; col < 10; col++) m[r][col] = 0.0;
    for (int k = 0; k <= i; k++) {
        const double *wk = weights + k * NP + 10 * i;
        double v[6] = {st->lin[k][0], st->lin[k][1], st->lin[k][2], st->ang[k][0], st->ang[k][1], st->ang[k][2]};
        for (int r = 0; r < 6; r++)
            for (int col = 0; col < 10; col++) m[r][col] += v[r] * wk[col];
    }
}

/* out = R0 Rot_axis(q) v: the inverse of rot_t (an adjoint's way back into the parent frame). */
static inline void rot(const double *r0, int axis, double c, double s, const double *v, double *out) {
    double u0, u1, u2;
    if (axis == 2) {
        u0 = c * v[0] - s * v[1]; u1 = s * v[0] + c * v[1]; u2 = v[2];
    } else if (axis == 1) {
        u0 = c * v[0] + s * v[2]; u1 = v[1]; u2 = c * v[2] - s * v[0];
    } else {
        u0 = v[0]; u1 = c * v[1] - s * v[2]; u2 = s * v[1] + c * v[2];
    }
    if (r0) {
        out[0] = r0[0] * u0 + r0[1] * u1 + r0[2] * u2;
        out[1] = r0[3] * u0 + r0[4] * u1 + r0[5] * u2;
        out[2] = r0[6] * u0 + r0[7] * u1 + r0[8] * u2;
    } else {
        out[0] = u0; out[1] = u1; out[2] = u2;
    }
}

static inline double dot3(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

/* Adds d<m, body_wrench(w, wd, a)>/d(w, wd, a) to gw, gwd, ga (body_wrench's entries differentiated by hand). */
static void wrench_adjoint(double m[6][10], const double *w, double *gw, double *gwd, double *ga) {
    ga[0] += m[0][0] + m[4][3] - m[5][2];
    ga[1] += m[1][0] - m[3][3] + m[5][1];
    ga[2] += m[2][0] + m[3][2] - m[4][1];
    gwd[0] += -m[1][3] + m[2][2] + m[3][4] - m[4][9] - m[5][8];
    gwd[1] += m[0][3] - m[2][1] - m[3][9] + m[4][5] - m[5][7];
    gwd[2] += -m[0][2] + m[1][1] - m[3][8] - m[4][7] + m[5][6];
    double cxx = -m[1][2] - m[2][3] + m[4][8] - m[5][9];
    double cyy = -m[0][1] - m[2][3] - m[3][7] + m[5][9];
    double czz = -m[0][1] - m[1][2] + m[3][7] - m[4][8];
    double cxy = m[0][2] + m[1][1] - m[3][8] + m[4][7] - m[5][4] + m[5][5];
    double cxz = m[0][3] + m[2][1] + m[3][9] + m[4][4] - m[4][6] - m[5][7];
    double cyz = m[1][3] + m[2][2] - m[3][5] + m[3][6] - m[4][9] + m[5][8];
    gw[0] += 2.0 * w[0] * cxx + w[1] * cxy + w[2] * cxz;
    gw[1] += 2.0 * w[1] * cyy + w[0] * cxy + w[2] * cyz;
    gw[2] += 2.0 * w[2] * czz + w[0] * cxz + w[1] * cyz;
}

/* out[18]: ds/dq_j, ds/dqd_j, ds/dqdd_j, exact, by reverse mode: one forward pass keeps each joint's
 * entering and leaving chain; a backward pass carries the adjoints of (w, wd, a, lin_k, ang_k) from
 * the last body to the first. A rotated vector v' = Rot(q)^T u has dv'/dq = v' x e (e: the axis). */
static void derive_sample(const double *geom, const unsigned char *axes, const int *identity, double eps,
                          const double *q, const double *qd, const double *qdd, const double *weights,
                          double *out, Py_ssize_t stride) {
    chain_state entry[NJ + 1];
    double cq[NJ], sq[NJ], y[NJ][6][10], m[6][10];
    const double *gravity = geom + 12 * NJ;
    memset(&entry[0], 0, sizeof(chain_state));
    entry[0].a[0] = -gravity[0]; entry[0].a[1] = -gravity[1]; entry[0].a[2] = -gravity[2];
    for (int i = 0; i < NJ; i++) {
        cq[i] = cos(q[i]); sq[i] = sin(q[i]);
        entry[i + 1] = entry[i];
        advance(geom, axes, identity, i, cq[i], sq[i], qd[i], qdd[i], &entry[i + 1], 1);
        body_wrench(entry[i + 1].w, entry[i + 1].wd, entry[i + 1].a, y[i]);
    }
    double gw[3] = {0, 0, 0}, gwd[3] = {0, 0, 0}, ga[3] = {0, 0, 0}, glin[NJ][3], gang[NJ][3];
    memset(glin, 0, sizeof glin); memset(gang, 0, sizeof gang);
    for (int i = NJ - 1; i >= 0; i--) {
        const chain_state *post = &entry[i + 1], *pre = &entry[i];
        const double *p = geom + 12 * i, *r0 = identity[i] ? NULL : geom + 12 * i + 3;
        int axis = axes[i];
        double c = cq[i], s = sq[i], e[3] = {0, 0, 0}, t[3], t2[3], t3[3];
        e[axis] = 1.0;
        /* body i's own term: through its wrench and through every motion vector k <= i */
        weight_map(post, i, weights, m);
        wrench_adjoint(m, post->w, gw, gwd, ga);
        for (int k = 0; k <= i; k++) {
            const double *wk = weights + k * NP + 10 * i;
            double f[6];
            for (int r = 0; r < 6; r++) {
                double total = 0.0;
                for (int col = 0; col < 10; col++) total += y[i][r][col] * wk[col];
                f[r] = total;
            }
            glin[k][0] += f[0]; glin[k][1] += f[1]; glin[k][2] += f[2];
            gang[k][0] += f[3]; gang[k][1] += f[4]; gang[k][2] += f[5];
        }
        /* back through advance(i): w' = W + qd e, wd' = D + qd (W x e) + qdd e, a' = A; W, D, A rotated */
        double we[3], dr[3], de[3], ae[3];
        cross3(post->w, e, we);                     /* W x e (W's axis component does not enter) */
        dr[0] = post->wd[0] - qd[i] * we[0]; dr[1] = post->wd[1] - qd[i] * we[1]; dr[2] = post->wd[2] - qd[i] * we[2];
        cross3(dr, e, de);
        cross3(post->a, e, ae);
        const double *wj = weights + i * NP;
        double th = tanh(qd[i] / eps);
        out[(12 + i) * stride] = gwd[axis] + wj[60 + i];
        out[(6 + i) * stride] = gw[axis] + dot3(gwd, we) + wj[66 + i] + wj[72 + i] * (1.0 - th * th) / eps;
        double gW[3];
        cross3(e, gwd, t);
        gW[0] = gw[0] + qd[i] * t[0]; gW[1] = gw[1] + qd[i] * t[1]; gW[2] = gw[2] + qd[i] * t[2];
        double dq = dot3(ga, ae) + dot3(gW, we) + dot3(gwd, de);
        for (int k = 0; k < i; k++) {
            cross3(post->lin[k], e, t); dq += dot3(glin[k], t);
            cross3(post->ang[k], e, t); dq += dot3(gang[k], t);
        }
        out[i * stride] = dq;
        /* into the parent frame: T = w x (w x p) + a + wd x p */
        double gT[3], nw[3], nwd[3];
        rot(r0, axis, c, s, ga, gT);
        rot(r0, axis, c, s, gW, nw);
        rot(r0, axis, c, s, gwd, nwd);
        cross3(p, gT, t); nwd[0] += t[0]; nwd[1] += t[1]; nwd[2] += t[2];
        cross3(pre->w, p, t2); cross3(t2, gT, t); nw[0] += t[0]; nw[1] += t[1]; nw[2] += t[2];
        cross3(gT, pre->w, t3); cross3(p, t3, t); nw[0] += t[0]; nw[1] += t[1]; nw[2] += t[2];
        memcpy(ga, gT, sizeof gT); memcpy(gw, nw, sizeof nw); memcpy(gwd, nwd, sizeof nwd);
        for (int k = 0; k < i; k++) {
            double lam[3];
            rot(r0, axis, c, s, glin[k], lam);
            rot(r0, axis, c, s, gang[k], t);
            cross3(p, lam, t2);
            gang[k][0] = t[0] + t2[0]; gang[k][1] = t[1] + t2[1]; gang[k][2] = t[2] + t2[2];
            memcpy(glin[k], lam, sizeof lam);
        }
    }
}

static PyObject *weighted_derivatives(PyObject *self, PyObject *args) {
    Py_buffer out, q, qd, qdd, weights, geom, axes;
    double eps;
    if (!PyArg_ParseTuple(args, "w*y*y*y*y*y*y*d", &out, &q, &qd, &qdd, &weights, &geom, &axes, &eps)) {
        return NULL;
    }
    Py_ssize_t n;
    int identity[NJ];
    int ok = chain_inputs(&q, &qd, &qdd, &geom, &axes, &n, identity)
          && weights.len == n * (Py_ssize_t)(sizeof(double) * NJ * NP)
          && out.len == n * (Py_ssize_t)(sizeof(double) * 3 * NJ);
    if (ok) {
        const double *pq = q.buf, *pqd = qd.buf, *pqdd = qdd.buf, *pw = weights.buf;
        double *po = out.buf;
        Py_BEGIN_ALLOW_THREADS
        for (Py_ssize_t k = 0; k < n; k++) {
            derive_sample(geom.buf, axes.buf, identity, eps, pq + NJ * k, pqd + NJ * k, pqdd + NJ * k,
                          pw + NJ * NP * k, po + k, n);
        }
        Py_END_ALLOW_THREADS
    }
    PyBuffer_Release(&out); PyBuffer_Release(&q); PyBuffer_Release(&qd); PyBuffer_Release(&qdd);
    PyBuffer_Release(&weights); PyBuffer_Release(&geom); PyBuffer_Release(&axes);
    if (!ok) {
        PyErr_SetString(PyExc_ValueError, "regressor kernel: inconsistent buffer sizes");
        return NULL;
    }
    Py_RETURN_NONE;
}

static PyMethodDef methods[] = {
    {"fill", fill, METH_VARARGS, "fill(out, q, qd, qdd, geometry, axes, eps): write the (N, 6, 78) regressor."},
    {"weighted_derivatives", weighted_derivatives, METH_VARARGS,
     "weighted_derivatives(out, q, qd, qdd, weights, geometry, axes, eps): write the (18, N) exact derivatives "
     "of sum(weights * regressor) per sample in q, qd and qdd."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_regressor_kernel", NULL, -1, methods};

PyMODINIT_FUNC PyInit__regressor_kernel(void) { return PyModule_Create(&module); }
