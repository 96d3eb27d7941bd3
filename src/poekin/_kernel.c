/*
 * poekin._kernel: the compiled forward-kinematics kernel.
 *
 * One generic interpreter serves every FK path (space PoE, body PoE, whole trees). Python
 * compiles a model into a small *program* of pose operations (see poekin/_fast.py); this file
 * runs it on blocks of LANES configurations at once, so that every operation is a loop over
 * lanes that the compiler turns into SIMD code, and on several threads for big batches.
 *
 * The state is one rigid transform per lane, ``cur = (R, t)``. Operations right-multiply it,
 * in the same order and with the same formulas as the pure-NumPy reference path
 * (poekin.chain.poe and poekin.tree.Tree._body_poses), so that both agree to ~1e-16.
 *
 * Floating point: built with -ffp-contract=off and without -ffast-math, so the result of one
 * configuration is the same bits whatever the batch size, the lane, the thread count or the
 * instruction set chosen at run time.
 *
 * sin and cos: a branch-free Cody-Waite reduction to a double-double remainder and fdlibm's
 * minimax kernels (error below 1 ulp), vectorised over lanes; arguments beyond 2^19 rad go to the C library's sin and cos.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#include <numpy/arrayobject.h>

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#ifdef _WIN32
#include <windows.h>
#else
#include <pthread.h>
#endif

#define LANES 8

/* Operation codes; each operation is 4 int32: code, qpos address, parameter offset, slot (for
 * SCREW and HINGE: the angle's index, 0, 1, ... in program order). */
enum {
    OP_IDENTITY = 0, /* cur = I */
    OP_LOAD = 1,     /* cur = slot[a3] */
    OP_STORE = 2,    /* slot[a3] = cur */
    OP_CONST = 3,    /* cur = cur * (R, t); params: R (9, row-major), t (3) */
    OP_SCREW = 4,    /* cur = cur * exp([S] q); params: W, W2 (9 each), r, u (3 each) */
    OP_HINGE = 5,    /* rotation about axis through anchor; params: scale, offset, ref, W, W2, anchor */
    OP_SLIDE = 6,    /* translation along axis; params: scale, offset, ref, axis */
    OP_BALL = 7,     /* rotation by the quaternion qpos[a:a+4] about anchor; params: anchor */
    OP_FREE = 8,     /* cur = (quat qpos[a+3:a+7], position qpos[a:a+3]) */
    OP_EMIT = 9,     /* write cur to output frame a3 */
};

enum { FORM_4X4 = 0, FORM_3X4 = 1, FORM_POS_QUAT = 2 };
static const int FORM_SIZE[3] = {16, 12, 7};

/* Work per thread below which another thread does not pay for its start. */
#define MIN_CONFIGS_PER_THREAD 8192
/* Batches at least this big run without the GIL. */
#define MIN_CONFIGS_NO_GIL 256
#define MAX_THREADS 256

static int g_threads = 1;

/* ------------------------------------------------------------------------------------------ */
/* sin and cos of LANES arguments */

#define INV_PIO2 6.36619772367581382433e-01 /* 2 / pi */
#define PIO2_1 1.57079632673412561417e+00   /* first 33 bits of pi/2 */
#define PIO2_2 6.07710050630396597660e-11   /* next 33 bits */
#define PIO2_3 2.02226624871116645580e-21   /* next 33 bits */
#define ROUND_MAGIC 6755399441055744.0      /* 1.5 * 2^52: adding it rounds to an integer */
#define REDUCE_MAX 524288.0                 /* 2^19: the reduction is exact below this */

#define S1 -1.66666666666666324348e-01
#define S2 8.33333333332248946124e-03
#define S3 -1.98412698298579493134e-04
#define S4 2.75573137070700676789e-06
#define S5 -2.50507602534068634195e-08
#define S6 1.58969099521155010221e-10
#define C1 4.16666666666666019037e-02
#define C2 -1.38888888888741095749e-03
#define C3 2.48015872894767294178e-05
#define C4 -2.75573143513906633035e-07
#define C5 2.08757232129817482790e-09
#define C6 -1.13596475577881948265e-11

#define AI static inline __attribute__((always_inline))

/* LANES configurations side by side: GCC vector types, lowered to the widest registers the
 * instruction set chosen at run time has (one zmm on AVX-512, two ymm on AVX2, four xmm). */
typedef double vd __attribute__((vector_size(8 * LANES)));
typedef int64_t vl __attribute__((vector_size(8 * LANES)));

AI vd vselect(vl mask, vd yes, vd no) { return (vd)(((vl)yes & mask) | ((vl)no & ~mask)); }

/* sin and cos of |x| < REDUCE_MAX: x = n pi/2 + (y0 + y1) with pi/2 to 99 bits, then fdlibm's
 * __kernel_sin(y0, y1) and __kernel_cos(y0, y1) by the last two bits of n. Lanes with a larger
 * |x| are then redone with the C library (sincos_fixup). */
AI void sincos_fast(vd x, vd *s, vd *c) {
    vd shifted = x * INV_PIO2 + ROUND_MAGIC;
    vd fn = shifted - ROUND_MAGIC;
    vl quadrant = (vl)shifted & 3;
    vd r1 = x - fn * PIO2_1; /* exact */
    vd w2 = fn * PIO2_2;     /* exact */
    vd r2 = r1 - w2;         /* r1 - w2 = r2 + e2 exactly (two-sum) */
    vd bv = r2 - r1;
    vd e2 = (r1 - (r2 - bv)) + (-w2 - bv);
    vd tail = e2 - fn * PIO2_3;
    vd y0 = r2 + tail; /* fast two-sum: |r2| >= |tail| */
    vd y1 = tail - (y0 - r2);
    vd z = y0 * y0;
    vd v = z * y0;
    vd rs = S2 + z * (S3 + z * (S4 + z * (S5 + z * S6)));
    vd sr = y0 - ((z * (0.5 * y1 - v * rs) - y1) - v * S1);
    vd rc = z * (C1 + z * (C2 + z * (C3 + z * (C4 + z * (C5 + z * C6)))));
    vd hz = 0.5 * z;
    vd w = 1.0 - hz;
    vd cr = w + (((1.0 - w) - hz) + (z * rc - y0 * y1));
    vl odd = (quadrant & 1) != 0;
    vd ss = vselect(odd, cr, sr), cc = vselect(odd, sr, cr);
    *s = vselect((quadrant & 2) != 0, -ss, ss);
    *c = vselect(((quadrant + 1) & 2) != 0, -cc, cc);
}

AI void sincos_fixup(vd x, vd *s, vd *c) {
    for (int l = 0; l < LANES; ++l) {
        if (!(fabs(x[l]) < REDUCE_MAX)) {
            (*s)[l] = sin(x[l]);
            (*c)[l] = cos(x[l]);
        }
    }
}

/* ------------------------------------------------------------------------------------------ */
/* rigid transforms: R (9, row-major) and t (3), each entry LANES wide */

typedef struct {
    vd R[9];
    vd t[3];
} Pose;

/* cur = cur * (Rj, tj): t += R tj, then R = R Rj (the reference's order and sums). */
AI void compose(Pose *cur, const vd *Rj, const vd *tj) {
    vd R[9];
    for (int k = 0; k < 9; ++k) R[k] = cur->R[k];
    for (int i = 0; i < 3; ++i)
        cur->t[i] = cur->t[i] + ((R[3 * i] * tj[0] + R[3 * i + 1] * tj[1]) + R[3 * i + 2] * tj[2]);
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            cur->R[3 * i + j] = (R[3 * i] * Rj[j] + R[3 * i + 1] * Rj[3 + j]) + R[3 * i + 2] * Rj[6 + j];
}

/* cur = cur * (R, t) for a constant R (9) and t (3). */
AI void compose_const(Pose *cur, const double *Rc, const double *tc) {
    vd R[9];
    for (int k = 0; k < 9; ++k) R[k] = cur->R[k];
    for (int i = 0; i < 3; ++i)
        cur->t[i] = cur->t[i] + ((R[3 * i] * tc[0] + R[3 * i + 1] * tc[1]) + R[3 * i + 2] * tc[2]);
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            cur->R[3 * i + j] = (R[3 * i] * Rc[j] + R[3 * i + 1] * Rc[3 + j]) + R[3 * i + 2] * Rc[6 + j];
}

/* Rj = (I + s W) + c W2, Rodrigues with c = 1 - cos. */
AI void rodrigues(const double *W, const double *W2, vd s, vd c, vd *Rj) {
    for (int k = 0; k < 9; ++k) Rj[k] = (((k % 4 == 0) ? 1.0 : 0.0) + s * W[k]) + c * W2[k];
}

/* tj = anchor - Rj anchor: the translation of a rotation about a point. */
AI void about_point(const double *anchor, const vd *Rj, vd *tj) {
    for (int i = 0; i < 3; ++i)
        tj[i] = anchor[i] -
                ((Rj[3 * i] * anchor[0] + Rj[3 * i + 1] * anchor[1]) + Rj[3 * i + 2] * anchor[2]);
}

/* Rj of the quaternion (w, x, y, z) = q[0..3], normalised as MuJoCo's mju_normalize4. */
AI void quat_rotation(const vd *q, vd *Rj) {
    vd w = q[0], x = q[1], y = q[2], z = q[3];
    vd norm2 = ((w * w + x * x) + y * y) + z * z, norm;
    for (int l = 0; l < LANES; ++l) norm[l] = sqrt(norm2[l]);
    vl tiny = norm < 1e-15;
    vl unchanged = (norm - 1.0 <= 1e-15) & (1.0 - norm <= 1e-15);
    vd zero = {0}, one = zero + 1.0;
    vd inv = one / vselect(tiny | unchanged, one, norm);
    w = vselect(tiny, one, w * inv);
    x = vselect(tiny, zero, x * inv);
    y = vselect(tiny, zero, y * inv);
    z = vselect(tiny, zero, z * inv);
    vd ww = w * w, xx = x * x, yy = y * y, zz = z * z;
    vd wx = w * x, wy = w * y, wz = w * z, xy = x * y, xz = x * z, yz = y * z;
    Rj[0] = ((ww + xx) - yy) - zz;
    Rj[1] = 2 * (xy - wz);
    Rj[2] = 2 * (xz + wy);
    Rj[3] = 2 * (xy + wz);
    Rj[4] = ((ww - xx) + yy) - zz;
    Rj[5] = 2 * (yz - wx);
    Rj[6] = 2 * (xz - wy);
    Rj[7] = 2 * (yz + wx);
    Rj[8] = ((ww - xx) - yy) + zz;
}

/* ------------------------------------------------------------------------------------------ */
/* output */

/* Quaternion wxyz with w >= 0 of R (Shepperd's method, as poekin.lie.rotation_to_quat). */
static inline __attribute__((always_inline)) void write_quat(const Pose *p, int l, double *o) {
    double m00 = p->R[0][l], m01 = p->R[1][l], m02 = p->R[2][l];
    double m10 = p->R[3][l], m11 = p->R[4][l], m12 = p->R[5][l];
    double m20 = p->R[6][l], m21 = p->R[7][l], m22 = p->R[8][l];
    double a = m21 - m12, b = m02 - m20, c = m10 - m01;
    double xy = m01 + m10, xz = m02 + m20, yz = m12 + m21;
    double d[4] = {1 + m00 + m11 + m22, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22,
                   1 - m00 - m11 + m22};
    int k = 0;
    for (int i = 1; i < 4; ++i)
        if (d[i] > d[k]) k = i;
    double big = sqrt(d[k] > 0.25 ? d[k] : 0.25) * 2;
    double q[4];
    switch (k) {
        case 0: q[0] = big / 4; q[1] = a / big; q[2] = b / big; q[3] = c / big; break;
        case 1: q[0] = a / big; q[1] = big / 4; q[2] = xy / big; q[3] = xz / big; break;
        case 2: q[0] = b / big; q[1] = xy / big; q[2] = big / 4; q[3] = yz / big; break;
        default: q[0] = c / big; q[1] = xz / big; q[2] = yz / big; q[3] = big / 4; break;
    }
    double sign = q[0] < 0 ? -1.0 : 1.0;
    for (int i = 0; i < 4; ++i) o[i] = q[i] * sign;
}

#if LANES == 8
/* r[e][l] -> r[l][e]: an 8x8 transpose in three rounds of two-vector shuffles. */
AI void transpose8(vd r[8]) {
    vd a[8], b[8];
    for (int k = 0; k < 8; k += 2) {
        a[k] = __builtin_shuffle(r[k], r[k + 1], (vl){0, 8, 2, 10, 4, 12, 6, 14});
        a[k + 1] = __builtin_shuffle(r[k], r[k + 1], (vl){1, 9, 3, 11, 5, 13, 7, 15});
    }
    for (int m = 0; m < 8; m += (m % 2 ? 3 : 1)) { /* m = 0, 1, 4, 5 */
        b[m] = __builtin_shuffle(a[m], a[m + 2], (vl){0, 1, 8, 9, 4, 5, 12, 13});
        b[m + 2] = __builtin_shuffle(a[m], a[m + 2], (vl){2, 3, 10, 11, 6, 7, 14, 15});
    }
    for (int m = 0; m < 4; ++m) {
        r[m] = __builtin_shuffle(b[m], b[m + 4], (vl){0, 1, 2, 3, 8, 9, 10, 11});
        r[m + 4] = __builtin_shuffle(b[m], b[m + 4], (vl){4, 5, 6, 7, 12, 13, 14, 15});
    }
}
#endif

/* Write each lane's pose to its row of the output, in the form asked for. */
static inline __attribute__((always_inline)) void emit(const Pose *p, int form, double *out,
                                                        npy_intp stride, int lanes) {
#if LANES == 8
    if (form != FORM_POS_QUAT) { /* rows [R0 R1 R2 t0 R3 R4 R5 t1 | R6 R7 R8 t2 0 0 0 1] */
        vd zero = {0};
        vd lo[8] = {p->R[0], p->R[1], p->R[2], p->t[0], p->R[3], p->R[4], p->R[5], p->t[1]};
        vd hi[8] = {p->R[6], p->R[7], p->R[8], p->t[2], zero, zero, zero, zero + 1.0};
        transpose8(lo);
        transpose8(hi);
        for (int l = 0; l < lanes; ++l) {
            double *o = out + l * stride;
            memcpy(o, &lo[l], sizeof(vd));
            if (form == FORM_4X4)
                memcpy(o + 8, &hi[l], sizeof(vd));
            else
                memcpy(o + 8, &hi[l], sizeof(vd) / 2);
        }
        return;
    }
#endif
    for (int l = 0; l < lanes; ++l) {
        double *o = out + l * stride;
        if (form == FORM_POS_QUAT) {
            o[0] = p->t[0][l];
            o[1] = p->t[1][l];
            o[2] = p->t[2][l];
            write_quat(p, l, o + 3);
            continue;
        }
        for (int i = 0; i < 3; ++i) {
            o[4 * i] = p->R[3 * i][l];
            o[4 * i + 1] = p->R[3 * i + 1][l];
            o[4 * i + 2] = p->R[3 * i + 2][l];
            o[4 * i + 3] = p->t[i][l];
        }
        if (form == FORM_4X4) {
            o[12] = 0.0;
            o[13] = 0.0;
            o[14] = 0.0;
            o[15] = 1.0;
        }
    }
}

/* ------------------------------------------------------------------------------------------ */
/* the interpreter */

typedef struct {
    const int32_t *ops;
    int n_ops;
    const double *params;
    int nq;
    int n_slots;
    int n_out;
    int n_angles;  /* SCREW and HINGE operations; each names its angle's index in its slot */
    double huge_q; /* a block with |q| beyond this may have an angle beyond REDUCE_MAX */
} Program;

typedef struct {
    const Program *prog;
    const double *q; /* (n, nq) */
    double *out;     /* (n, n_out, FORM_SIZE[form]) */
    npy_intp lo, hi;
    int form;
    int bad; /* set if some q is not finite */
} Task;

#if defined(__x86_64__) && defined(__ELF__) && defined(__GNUC__) && !defined(__clang__)
#define MULTI_ISA __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#else
#define MULTI_ISA
#endif

typedef struct {
    vd th, s, c; /* angle, sin, 1 - cos */
} Angle;

/* Run the program on one block of LANES configurations, q transposed in qT; slots hold the
 * stored poses, ang the angles. huge: some |q| may give an angle beyond REDUCE_MAX. */
AI void run_ops(const Program *prog, Pose *restrict slots, const vd *restrict qT,
                Angle *restrict ang, double *out, int form, int lanes, int huge) {
    const int size = FORM_SIZE[form];
    const npy_intp stride = (npy_intp)prog->n_out * size;
    Pose cur;
    /* first every angle, then their sin and 1 - cos two at a time: independent work whose
     * latencies overlap */
    for (int k = 0; k < prog->n_ops; ++k) {
        const int32_t *op = prog->ops + 4 * k;
        const double *P = prog->params + op[2];
        if (op[0] == OP_SCREW) ang[op[3]].th = qT[op[1]];
        if (op[0] == OP_HINGE) ang[op[3]].th = (qT[op[1]] * P[0] + P[1]) - P[2];
    }
    for (int k = 0; k < prog->n_angles; k += 2) {
        Angle *A = ang + k, *B = ang + (k + 1 < prog->n_angles ? k + 1 : k);
        vd sa, ca, sb, cb;
        sincos_fast(A->th, &sa, &ca);
        sincos_fast(B->th, &sb, &cb);
        if (huge) {
            sincos_fixup(A->th, &sa, &ca);
            sincos_fixup(B->th, &sb, &cb);
        }
        A->s = sa;
        A->c = 1.0 - ca;
        B->s = sb;
        B->c = 1.0 - cb;
    }
    for (int k = 0; k < prog->n_ops; ++k) {
        const int32_t *op = prog->ops + 4 * k;
        const int a = op[1], slot = op[3];
        const double *P = prog->params + op[2];
        vd Rj[9], tj[3];
        switch (op[0]) {
            case OP_IDENTITY:
                for (int i = 0; i < 9; ++i) cur.R[i] = (vd){0} + ((i % 4 == 0) ? 1.0 : 0.0);
                for (int i = 0; i < 3; ++i) cur.t[i] = (vd){0};
                break;
            case OP_LOAD:
                cur = slots[slot];
                break;
            case OP_STORE:
                slots[slot] = cur;
                break;
            case OP_CONST:
                compose_const(&cur, P, P + 9);
                break;
            case OP_SCREW: /* R = (I + s W) + c W2, c = 1 - cos q; p = (r - R r) + q u */
                rodrigues(P, P + 9, ang[slot].s, ang[slot].c, Rj);
                about_point(P + 18, Rj, tj);
                for (int i = 0; i < 3; ++i) tj[i] = tj[i] + ang[slot].th * P[21 + i];
                compose(&cur, Rj, tj);
                break;
            case OP_HINGE:
                rodrigues(P + 3, P + 12, ang[slot].s, ang[slot].c, Rj);
                about_point(P + 21, Rj, tj);
                compose(&cur, Rj, tj);
                break;
            case OP_SLIDE: {
                vd th = (qT[a] * P[0] + P[1]) - P[2];
                for (int i = 0; i < 3; ++i) {
                    vd ax = (cur.R[3 * i] * P[3] + cur.R[3 * i + 1] * P[4]) + cur.R[3 * i + 2] * P[5];
                    cur.t[i] = cur.t[i] + ax * th;
                }
                break;
            }
            case OP_BALL:
                quat_rotation(qT + a, Rj);
                about_point(P, Rj, tj);
                compose(&cur, Rj, tj);
                break;
            case OP_FREE:
                quat_rotation(qT + a + 3, cur.R);
                for (int i = 0; i < 3; ++i) cur.t[i] = qT[a + i];
                break;
            case OP_EMIT:
                emit(&cur, form, out + (npy_intp)slot * size, stride, lanes);
                break;
        }
    }
}

MULTI_ISA static void run_block(const Program *prog, const double *q, npy_intp n_rows,
                                double *out, int form, Pose *slots, vd *qT, Angle *ang,
                                int *bad) {
    const int nq = prog->nq;
    const int lanes = n_rows < LANES ? (int)n_rows : LANES;
    const double huge_q = prog->huge_q;
    /* transpose the block's q to qT[j][lane]; lanes past the end repeat the last row */
    const vl sign = (vl){0} + INT64_MAX;
    const vd limit = (vd){0} + huge_q;
    vl below = (vl){0} - 1; /* per lane: every |q| < huge_q (false for NaN and inf too) */
    for (int j = 0; j < nq; ++j) {
        vd v;
        if (lanes == LANES) {
            for (int l = 0; l < LANES; ++l) v[l] = q[l * nq + j];
        } else {
            for (int l = 0; l < LANES; ++l) v[l] = q[(l < lanes ? l : lanes - 1) * nq + j];
        }
        qT[j] = v;
        below &= (vd)((vl)v & sign) < limit;
    }
    int ok = 1;
    for (int l = 0; l < LANES; ++l) ok &= below[l] != 0;
    if (!ok) {
        for (int j = 0; j < nq; ++j)
            for (int l = 0; l < LANES; ++l)
                if (!isfinite(qT[j][l])) {
                    *bad = 1;
                    return;
                }
    }
    run_ops(prog, slots, qT, ang, out, form, lanes, !ok);
}

/* Scratch that fits in this many bytes lives on the stack (no malloc per call). */
#define STACK_SCRATCH 32768

static unsigned char *aligned_malloc(size_t bytes) {
    size_t rounded = (bytes + sizeof(vd) - 1) / sizeof(vd) * sizeof(vd);
#ifdef _WIN32
    return _aligned_malloc(rounded, sizeof(vd));
#else
    return aligned_alloc(sizeof(vd), rounded);
#endif
}

static void aligned_free(unsigned char *p) {
#ifdef _WIN32
    _aligned_free(p);
#else
    free(p);
#endif
}

static void run_task(Task *task) {
    const Program *prog = task->prog;
    const npy_intp stride = (npy_intp)prog->n_out * FORM_SIZE[task->form];
    size_t n_slots = prog->n_slots, n_q = prog->nq, n_ang = prog->n_angles;
    size_t bytes = sizeof(Pose) * n_slots + sizeof(vd) * n_q + sizeof(Angle) * n_ang;
    _Alignas(64) unsigned char stack[STACK_SCRATCH];
    unsigned char *heap = bytes > STACK_SCRATCH ? aligned_malloc(bytes) : NULL;
    unsigned char *base = bytes > STACK_SCRATCH ? heap : stack;
    if (base == NULL) {
        task->bad = -1;
        return;
    }
    /* every part's size is a multiple of sizeof(vd), so each stays aligned */
    Pose *slots = (Pose *)base;
    vd *qT = (vd *)(base + sizeof(Pose) * n_slots);
    Angle *ang = (Angle *)(base + sizeof(Pose) * n_slots + sizeof(vd) * n_q);
    for (npy_intp i = task->lo; i < task->hi && !task->bad; i += LANES) {
        npy_intp rows = task->hi - i < LANES ? task->hi - i : LANES;
        run_block(prog, task->q + i * prog->nq, rows, task->out + i * stride, task->form, slots,
                  qT, ang, &task->bad);
    }
    aligned_free(heap);
}

#ifdef _WIN32
static DWORD WINAPI thread_main(LPVOID arg) {
    run_task((Task *)arg);
    return 0;
}
#else
static void *thread_main(void *arg) {
    run_task((Task *)arg);
    return NULL;
}
#endif

/* Run prog on n configurations on up to g_threads threads. 0: done, 1: a q is not finite,
 * -1: out of memory. */
static int run_program(const Program *prog, const double *q, npy_intp n, double *out, int form,
                       int threads) {
    Task tasks[MAX_THREADS];
    npy_intp most = n / MIN_CONFIGS_PER_THREAD;
    int nt = threads < most ? threads : (int)(most > 0 ? most : 1);
    if (nt > MAX_THREADS) nt = MAX_THREADS;
    npy_intp chunk = (n + nt - 1) / nt;
    chunk = (chunk + LANES - 1) / LANES * LANES;
    for (int k = 0; k < nt; ++k) {
        npy_intp lo = k * chunk < n ? k * chunk : n;
        npy_intp hi = lo + chunk < n ? lo + chunk : n;
        tasks[k] = (Task){prog, q, out, lo, hi, form, 0};
    }
#ifdef _WIN32
    HANDLE handles[MAX_THREADS];
#else
    pthread_t handles[MAX_THREADS];
#endif
    int started[MAX_THREADS];
    for (int k = 1; k < nt; ++k) {
#ifdef _WIN32
        handles[k] = CreateThread(NULL, 0, thread_main, &tasks[k], 0, NULL);
        started[k] = handles[k] != NULL;
#else
        started[k] = pthread_create(&handles[k], NULL, thread_main, &tasks[k]) == 0;
#endif
    }
    run_task(&tasks[0]);
    int status = tasks[0].bad;
    for (int k = 1; k < nt; ++k) {
        if (started[k]) {
#ifdef _WIN32
            WaitForSingleObject(handles[k], INFINITE);
            CloseHandle(handles[k]);
#else
            pthread_join(handles[k], NULL);
#endif
        } else {
            run_task(&tasks[k]); /* no thread to be had: do its share here */
        }
        if (tasks[k].bad && !status) status = tasks[k].bad;
    }
    return status;
}

/* ------------------------------------------------------------------------------------------ */
/* Python type: Kernel(ops, params, nq, n_slots, n_out, frame_axis) */

typedef struct {
    PyObject_HEAD Program prog;
    PyObject *ops_obj;    /* keeps the int32 ops array alive */
    PyObject *params_obj; /* keeps the float64 params array alive */
    int frame_axis;       /* output shape (..., n_out, ...) rather than (...) */
} KernelObject;

/* Pickling and copying: rebuild from the constructor's arguments. */
static PyObject *Kernel_reduce(KernelObject *self, PyObject *Py_UNUSED(ignored)) {
    return Py_BuildValue("O(OOiiii)", Py_TYPE(self), self->ops_obj, self->params_obj,
                         self->prog.nq, self->prog.n_slots, self->prog.n_out, self->frame_axis);
}

static void Kernel_dealloc(KernelObject *self) {
    Py_XDECREF(self->ops_obj);
    Py_XDECREF(self->params_obj);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static int Kernel_init(KernelObject *self, PyObject *args, PyObject *kwds) {
    static char *kwlist[] = {"ops", "params", "nq", "n_slots", "n_out", "frame_axis", NULL};
    PyObject *ops, *params;
    int nq, n_slots, n_out, frame_axis;
    if (!PyArg_ParseTupleAndKeywords(args, kwds, "OOiiip", kwlist, &ops, &params, &nq, &n_slots,
                                     &n_out, &frame_axis))
        return -1;
    PyArrayObject *o = (PyArrayObject *)PyArray_FROMANY(ops, NPY_INT32, 2, 2, NPY_ARRAY_CARRAY);
    if (o == NULL) return -1;
    PyArrayObject *p = (PyArrayObject *)PyArray_FROMANY(params, NPY_FLOAT64, 1, 1, NPY_ARRAY_CARRAY);
    if (p == NULL) {
        Py_DECREF(o);
        return -1;
    }
    if (PyArray_DIM(o, 1) != 4 || nq < 0 || n_slots < 0 || n_out < 1) {
        Py_DECREF(o);
        Py_DECREF(p);
        PyErr_SetString(PyExc_ValueError, "ops must be (n, 4), nq >= 0, n_slots >= 0, n_out >= 1");
        return -1;
    }
    /* check every operation's operands, so that running the program cannot go out of bounds */
    const int32_t *code = PyArray_DATA(o);
    npy_intp n_ops = PyArray_DIM(o, 0), n_params = PyArray_DIM(p, 0);
    int n_angles = 0;
    static const int QSIZE[10] = {0, 0, 0, 0, 1, 1, 1, 4, 7, 0};
    static const int PSIZE[10] = {0, 0, 0, 12, 24, 24, 6, 3, 0, 0};
    for (npy_intp k = 0; k < n_ops; ++k) {
        const int32_t *op = code + 4 * k;
        int ok = op[0] >= 0 && op[0] <= OP_EMIT && op[1] >= 0 && op[1] + QSIZE[op[0]] <= nq &&
                 op[2] >= 0 && op[2] + PSIZE[op[0]] <= n_params;
        if (ok && (op[0] == OP_LOAD || op[0] == OP_STORE)) ok = op[3] >= 0 && op[3] < n_slots;
        if (ok && op[0] == OP_EMIT) ok = op[3] >= 0 && op[3] < n_out;
        if (ok && (op[0] == OP_SCREW || op[0] == OP_HINGE)) ok = op[3] == n_angles++;
        if (!ok) {
            Py_DECREF(o);
            Py_DECREF(p);
            PyErr_Format(PyExc_ValueError, "operation %zd is out of range", (Py_ssize_t)k);
            return -1;
        }
    }
    Py_XSETREF(self->ops_obj, (PyObject *)o);
    Py_XSETREF(self->params_obj, (PyObject *)p);
    /* the angles are q (screws) or (q scale + offset) - ref (hinges): bound them */
    double gain = 1.0, shift = 0.0;
    const double *pd = PyArray_DATA(p);
    for (npy_intp k = 0; k < n_ops; ++k) {
        if (code[4 * k] != OP_HINGE) continue;
        const double *P = pd + code[4 * k + 2];
        if (fabs(P[0]) > gain) gain = fabs(P[0]);
        if (fabs(P[1]) + fabs(P[2]) > shift) shift = fabs(P[1]) + fabs(P[2]);
    }
    double huge_q = (REDUCE_MAX - shift) / gain;
    self->prog = (Program){code, (int)n_ops, pd, nq, n_slots, n_out, n_angles,
                           huge_q > 0 ? huge_q : 0.0};
    self->frame_axis = frame_axis;
    return 0;
}

/* run(q, out=None, form=0): the poses of q, or None if q is not a C-contiguous float64 array
 * of shape (..., nq) with finite values (the caller then validates and converts it). */
static PyObject *Kernel_run(KernelObject *self, PyObject *const *args, Py_ssize_t nargs) {
    if (nargs < 1 || nargs > 3) {
        PyErr_SetString(PyExc_TypeError, "run(q, out=None, form=0)");
        return NULL;
    }
    const Program *prog = &self->prog;
    PyObject *qobj = args[0];
    if (!PyArray_CheckExact(qobj)) Py_RETURN_NONE;
    PyArrayObject *q = (PyArrayObject *)qobj;
    int nd = PyArray_NDIM(q);
    if (nd < 1 || PyArray_TYPE(q) != NPY_FLOAT64 || !PyArray_IS_C_CONTIGUOUS(q) ||
        !PyArray_ISALIGNED(q) || PyArray_ISBYTESWAPPED(q) || PyArray_DIM(q, nd - 1) != prog->nq)
        Py_RETURN_NONE;
    int form = FORM_4X4;
    if (nargs == 3) {
        form = PyLong_AsLong(args[2]);
        if (form == -1 && PyErr_Occurred()) return NULL;
        if (form < 0 || form > 2) {
            PyErr_SetString(PyExc_ValueError, "form must be 0, 1 or 2");
            return NULL;
        }
    }
    npy_intp dims[NPY_MAXDIMS];
    int out_nd = 0;
    npy_intp n = 1;
    for (int i = 0; i < nd - 1; ++i) {
        dims[out_nd++] = PyArray_DIM(q, i);
        n *= PyArray_DIM(q, i);
    }
    if (out_nd + 3 > NPY_MAXDIMS) Py_RETURN_NONE;
    if (self->frame_axis) dims[out_nd++] = prog->n_out;
    if (form == FORM_POS_QUAT) {
        dims[out_nd++] = 7;
    } else {
        dims[out_nd++] = form == FORM_4X4 ? 4 : 3;
        dims[out_nd++] = 4;
    }
    PyArrayObject *out;
    if (nargs >= 2 && args[1] != Py_None) {
        out = (PyArrayObject *)args[1];
        if (!PyArray_Check(args[1]) || PyArray_TYPE(out) != NPY_FLOAT64 ||
            !PyArray_IS_C_CONTIGUOUS(out) || !PyArray_ISALIGNED(out) ||
            !PyArray_ISWRITEABLE(out) || PyArray_ISBYTESWAPPED(out) ||
            PyArray_NDIM(out) != out_nd ||
            !PyArray_CompareLists(PyArray_DIMS(out), dims, out_nd)) {
            PyErr_SetString(PyExc_ValueError, "out must be a writeable C-contiguous float64 "
                                              "array of the result's shape");
            return NULL;
        }
        Py_INCREF(out);
    } else {
        out = (PyArrayObject *)PyArray_SimpleNew(out_nd, dims, NPY_FLOAT64);
        if (out == NULL) return NULL;
    }
    int status = 0;
    if (n > 0) {
        const double *qd = PyArray_DATA(q);
        double *od = PyArray_DATA(out);
        if (n >= MIN_CONFIGS_NO_GIL) {
            int threads = g_threads;
            Py_BEGIN_ALLOW_THREADS status = run_program(prog, qd, n, od, form, threads);
            Py_END_ALLOW_THREADS
        } else {
            status = run_program(prog, qd, n, od, form, 1);
        }
    }
    if (status == 0) return (PyObject *)out;
    Py_DECREF(out);
    if (status < 0) return PyErr_NoMemory();
    Py_RETURN_NONE; /* a value is NaN or inf: the caller's validation says which */
}

static PyMethodDef Kernel_methods[] = {
    {"run", (PyCFunction)(void (*)(void))Kernel_run, METH_FASTCALL,
     "run(q, out=None, form=0) -> poses, or None if q needs validating first"},
    {"__reduce__", (PyCFunction)Kernel_reduce, METH_NOARGS, NULL},
    {NULL, NULL, 0, NULL},
};

static PyTypeObject KernelType = {
    PyVarObject_HEAD_INIT(NULL, 0).tp_name = "poekin._kernel.Kernel",
    .tp_basicsize = sizeof(KernelObject),
    .tp_dealloc = (destructor)Kernel_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "A compiled forward-kinematics program (built by poekin._fast).",
    .tp_methods = Kernel_methods,
    .tp_init = (initproc)Kernel_init,
    .tp_new = PyType_GenericNew,
};

static PyObject *set_threads(PyObject *Py_UNUSED(mod), PyObject *arg) {
    long n = PyLong_AsLong(arg);
    if (n == -1 && PyErr_Occurred()) return NULL;
    if (n < 1 || n > MAX_THREADS) {
        PyErr_Format(PyExc_ValueError, "threads must be 1 to %d", MAX_THREADS);
        return NULL;
    }
    g_threads = (int)n;
    Py_RETURN_NONE;
}

static PyObject *get_threads(PyObject *Py_UNUSED(mod), PyObject *Py_UNUSED(unused)) {
    return PyLong_FromLong(g_threads);
}

static PyMethodDef module_methods[] = {
    {"set_threads", set_threads, METH_O, "set_threads(n): threads for big batches"},
    {"get_threads", get_threads, METH_NOARGS, "get_threads() -> int"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module_def = {
    PyModuleDef_HEAD_INIT, "poekin._kernel", "Compiled forward-kinematics kernel.", -1,
    module_methods, NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__kernel(void) {
    import_array();
    if (PyType_Ready(&KernelType) < 0) return NULL;
    PyObject *m = PyModule_Create(&module_def);
    if (m == NULL) return NULL;
    Py_INCREF(&KernelType);
    if (PyModule_AddObject(m, "Kernel", (PyObject *)&KernelType) < 0) {
        Py_DECREF(&KernelType);
        Py_DECREF(m);
        return NULL;
    }
    PyModule_AddIntConstant(m, "LANES", LANES);
    return m;
}
