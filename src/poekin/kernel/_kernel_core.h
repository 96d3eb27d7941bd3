/*
 * The part of poekin's FK kernel that depends on LANES, the number of configurations computed
 * side by side. _kernel.c includes it once per width, each time with LANES and TARGET (the
 * instruction set) defined; every name below gets the width as a suffix (run_task_8, ...).
 */
#define GLUE_(a, b) a##_##b
#define GLUE(a, b) GLUE_(a, b)
#define vd GLUE(vd, LANES)
#define vl GLUE(vl, LANES)
#define vd_unaligned GLUE(vd_unaligned, LANES)
#define vselect GLUE(vselect, LANES)
#define sincos_fast GLUE(sincos_fast, LANES)
#define sincos_fixup GLUE(sincos_fixup, LANES)
#define Pose GLUE(Pose, LANES)
#define copy_pose GLUE(copy_pose, LANES)
#define compose GLUE(compose, LANES)
#define compose_const GLUE(compose_const, LANES)
#define rodrigues GLUE(rodrigues, LANES)
#define about_point GLUE(about_point, LANES)
#define jacobian_column GLUE(jacobian_column, LANES)
#define jacobian_emit GLUE(jacobian_emit, LANES)
#define world_velocity GLUE(world_velocity, LANES)
#define axis_turn GLUE(axis_turn, LANES)
#define quat_rotation GLUE(quat_rotation, LANES)
#define rotation_quat GLUE(rotation_quat, LANES)
#define pose_quat GLUE(pose_quat, LANES)
#define transpose8 GLUE(transpose8, LANES)
#define transpose4 GLUE(transpose4, LANES)
#define store_rows GLUE(store_rows, LANES)
#define emit GLUE(emit, LANES)
#define Angle GLUE(Angle, LANES)
#define run_ops GLUE(run_ops, LANES)
#define run_block GLUE(run_block, LANES)
#define run_task GLUE(run_task, LANES)

/* LANES configurations side by side: GCC vector types, lowered to the widest registers the
 * instruction set chosen at run time has (one zmm on AVX-512, two ymm on AVX2, four xmm). */
typedef double vd __attribute__((vector_size(8 * LANES)));
typedef int64_t vl __attribute__((vector_size(8 * LANES)));
/* For one unaligned store of a whole vector: GCC splits a memcpy of one into 16-byte moves,
 * or into rep movs when its size is not a constant. */
typedef double vd_unaligned __attribute__((vector_size(8 * LANES), aligned(8), may_alias));

#if LANES == 4
/* one blend; the generic form below is three instructions (GCC does not fuse them) */
AI vd vselect(vl mask, vd yes, vd no) {
    return __builtin_ia32_blendvpd256(no, yes, (vd)mask);
}
#else
AI vd vselect(vl mask, vd yes, vd no) { return (vd)(((vl)yes & mask) | ((vl)no & ~mask)); }
#endif

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

typedef struct {
    vd th, s, c; /* angle, sin, cos */
} Angle;

/* *dst = *src one vector at a time (GCC copies a whole Pose with rep movs) */
AI void copy_pose(Pose *restrict dst, const Pose *restrict src) {
    for (int k = 0; k < 9; ++k) dst->R[k] = src->R[k];
    for (int i = 0; i < 3; ++i) dst->t[i] = src->t[i];
}

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

/* cur = cur * (R, t) for a constant R (9) and t (3), the same in every lane. */
AI void compose_const(Pose *cur, const double *Rc, const double *tc) {
    vd R[9], t[3];
    for (int k = 0; k < 9; ++k) R[k] = Rc[k] - (vd){0}; /* x - 0 keeps the sign of 0 */
    for (int i = 0; i < 3; ++i) t[i] = tc[i] - (vd){0};
    compose(cur, R, t);
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

/* cur = cur * (Rk, (point - Rk point) + th pitch e_k) for Rk the rotation about coordinate axis
 * k with cos c and sin s: rows a = k+1, b = k+2 (mod 3) of point are pa, pb, and its row k
 * cancels. Only columns a and b of R change, each c R_a + s R_b or c R_b - s R_a: the arithmetic
 * of the full product with Rk's zeros and ones left out, equal to it but for signs of zero.
 * Params: scale, offset, ref, sign, point[a], point[b], pitch. */
AI void axis_turn(Pose *cur, const int k, const int pitched, const Angle *A, const double *P) {
    const int a = (k + 1) % 3, b = (k + 2) % 3;
    const vd s = P[3] * A->s, c = A->c;
    const double ra = P[4], rb = P[5];
    vd pj[3];
    pj[a] = ra - (c * ra - s * rb);
    pj[b] = rb - (s * ra + c * rb);
    if (pitched) {
        pj[k] = A->th * P[6];
        for (int i = 0; i < 3; ++i)
            cur->t[i] = cur->t[i] + ((cur->R[3 * i] * pj[0] + cur->R[3 * i + 1] * pj[1]) +
                                     cur->R[3 * i + 2] * pj[2]);
    } else {
        for (int i = 0; i < 3; ++i)
            cur->t[i] = cur->t[i] + (cur->R[3 * i + a] * pj[a] + cur->R[3 * i + b] * pj[b]);
    }
    for (int i = 0; i < 3; ++i) {
        vd *R = cur->R + 3 * i;
        vd Ra = R[a], Rb = R[b];
        R[a] = c * Ra + s * Rb;
        R[b] = c * Rb - s * Ra;
    }
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

/* Quaternion wxyz with w >= 0 of the rotation M (9, row-major; Shepperd's method, as
 * poekin._pose.rotation_quat): the largest component from the diagonal (the first of equals),
 * the others divided by it. */
AI void rotation_quat(const vd *M, vd *q) {
    vd a = M[7] - M[5], b = M[2] - M[6], c = M[3] - M[1];
    vd xy = M[1] + M[3], xz = M[2] + M[6], yz = M[5] + M[7];
    vd d[4] = {((1 + M[0]) + M[4]) + M[8], ((1 + M[0]) - M[4]) - M[8],
               ((1 - M[0]) + M[4]) - M[8], ((1 - M[0]) - M[4]) + M[8]};
    vd best = d[0];
    vl k = {0};
    for (int i = 1; i < 4; ++i) {
        vl more = d[i] > best;
        best = vselect(more, d[i], best);
        k = (vl)vselect(more, (vd)((vl){0} + i), (vd)k);
    }
    vd big = vselect(best > 0.25, best, (vd){0} + 0.25);
    for (int l = 0; l < LANES; ++l) big[l] = sqrt(big[l]);
    big = big * 2;
    /* numerator of component i when component j is the largest: (a, b, c) against w, xy, xz,
     * yz between x, y, z */
    const vd *num[4][4] = {{NULL, &a, &b, &c}, {&a, NULL, &xy, &xz}, {&b, &xy, NULL, &yz},
                           {&c, &xz, &yz, NULL}};
    for (int i = 0; i < 4; ++i) {
        vd top = big / 4; /* where component i is the largest */
        for (int j = 0; j < 4; ++j)
            if (j != i) top = vselect(k == j, *num[i][j], top);
        q[i] = vselect(k == i, top, top / big);
    }
    vl negative = q[0] < 0;
    for (int i = 0; i < 4; ++i) q[i] = vselect(negative, -q[i], q[i]);
}

AI void pose_quat(const Pose *p, vd *q) { rotation_quat(p->R, q); }

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

#if LANES == 4
/* r[e][l] -> r[l][e]: a 4x4 transpose in two rounds of two-vector shuffles. */
AI void transpose4(vd r[4]) {
    vd a0 = __builtin_shuffle(r[0], r[1], (vl){0, 4, 2, 6});
    vd a1 = __builtin_shuffle(r[0], r[1], (vl){1, 5, 3, 7});
    vd a2 = __builtin_shuffle(r[2], r[3], (vl){0, 4, 2, 6});
    vd a3 = __builtin_shuffle(r[2], r[3], (vl){1, 5, 3, 7});
    r[0] = __builtin_shuffle(a0, a2, (vl){0, 1, 4, 5});
    r[1] = __builtin_shuffle(a1, a3, (vl){0, 1, 4, 5});
    r[2] = __builtin_shuffle(a0, a2, (vl){2, 3, 6, 7});
    r[3] = __builtin_shuffle(a1, a3, (vl){2, 3, 6, 7});
}
#endif

#if LANES == 8
/* Lane l's pose from the transposed halves lo and hi: 16 numbers for 4x4, 12 for 3x4. */
AI void store_rows(const vd lo[8], const vd hi[8], int l, int form, double *o) {
    typedef double half __attribute__((vector_size(32)));
    typedef double half_unaligned __attribute__((vector_size(32), aligned(8), may_alias));
    *(vd_unaligned *)o = lo[l];
    if (form == FORM_4X4)
        *(vd_unaligned *)(o + 8) = hi[l];
    else
        *(half_unaligned *)(o + 8) = (half){hi[l][0], hi[l][1], hi[l][2], hi[l][3]};
}
#endif

#if LANES == 4
/* Lane l's pose from transposed rows: [R_i0 R_i1 R_i2 t_i] for i < 3, then [0 0 0 1] for 4x4. */
AI void store_rows(vd rows[3][4], int l, int form, double *o) {
    const vd last = {0.0, 0.0, 0.0, 1.0};
    for (int i = 0; i < 3; ++i) *(vd_unaligned *)(o + 4 * i) = rows[i][l];
    if (form == FORM_4X4) *(vd_unaligned *)(o + 12) = last;
}
#endif

/* Write each lane's pose to its row of the output, in the form asked for. */
AI void emit(const Pose *p, int form, double *out, npy_intp stride, int lanes) {
#if LANES == 8
    if (form != FORM_POS_QUAT) { /* rows [R0 R1 R2 t0 R3 R4 R5 t1 | R6 R7 R8 t2 0 0 0 1] */
        vd zero = {0};
        vd lo[8] = {p->R[0], p->R[1], p->R[2], p->t[0], p->R[3], p->R[4], p->R[5], p->t[1]};
        vd hi[8] = {p->R[6], p->R[7], p->R[8], p->t[2], zero, zero, zero, zero + 1.0};
        transpose8(lo);
        transpose8(hi);
        if (lanes == LANES) /* a constant count: the stores unroll */
            for (int l = 0; l < LANES; ++l) store_rows(lo, hi, l, form, out + l * stride);
        else
            for (int l = 0; l < lanes; ++l) store_rows(lo, hi, l, form, out + l * stride);
        return;
    }
#endif
#if LANES == 4
    if (form != FORM_POS_QUAT) { /* each row [R_i0 R_i1 R_i2 t_i] of a lane: one store */
        vd rows[3][4];
        for (int i = 0; i < 3; ++i) {
            vd *r = rows[i];
            r[0] = p->R[3 * i], r[1] = p->R[3 * i + 1], r[2] = p->R[3 * i + 2], r[3] = p->t[i];
            transpose4(r);
        }
        if (lanes == LANES) /* a constant count: the stores unroll */
            for (int l = 0; l < LANES; ++l) store_rows(rows, l, form, out + l * stride);
        else
            for (int l = 0; l < lanes; ++l) store_rows(rows, l, form, out + l * stride);
        return;
    }
#endif
    if (form == FORM_POS_QUAT) {
        vd q[4];
        pose_quat(p, q);
#if LANES == 4
        /* lane l's [t0 t1 t2 q0] and [q0 q1 q2 q3]: two stores that overlap at q0 */
        vd head[4] = {p->t[0], p->t[1], p->t[2], q[0]}, tail[4] = {q[0], q[1], q[2], q[3]};
        transpose4(head);
        transpose4(tail);
        for (int l = 0; l < lanes; ++l) {
            *(vd_unaligned *)(out + l * stride) = head[l];
            *(vd_unaligned *)(out + l * stride + 3) = tail[l];
        }
#else
        for (int l = 0; l < lanes; ++l) {
            double *o = out + l * stride;
            for (int i = 0; i < 3; ++i) o[i] = p->t[i][l];
            for (int i = 0; i < 4; ++i) o[3 + i] = q[i][l];
        }
#endif
        return;
    }
    for (int l = 0; l < lanes; ++l) {
        double *o = out + l * stride;
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

/* col += P[6] Ad(cur) [w; v] for the screw (w, v) = P[0..5]: [a; p x a + R v] with a = R w,
 * the sums in poekin._poe.space_jacobian's order; P[6] is 1, or a mimic joint's multiplier. */
AI void jacobian_column(const Pose *cur, const double *P, vd *col) {
    const vd *R = cur->R, *p = cur->t;
    vd a[3], Rv[3];
    for (int i = 0; i < 3; ++i) {
        a[i] = (R[3 * i] * P[0] + R[3 * i + 1] * P[1]) + R[3 * i + 2] * P[2];
        Rv[i] = (R[3 * i] * P[3] + R[3 * i + 1] * P[4]) + R[3 * i + 2] * P[5];
    }
    const vd c[6] = {a[0], a[1], a[2], (p[1] * a[2] - p[2] * a[1]) + Rv[0],
                     (p[2] * a[0] - p[0] * a[2]) + Rv[1], (p[0] * a[1] - p[1] * a[0]) + Rv[2]};
    for (int r = 0; r < 6; ++r) col[r] = col[r] + P[6] * c[r];
}

/* v + a x p for a space column col = [a; v]: the velocity of the point p (the frame's origin)
 * in the world frame (poekin._poe.world_columns). */
AI void world_velocity(const vd *col, const vd *p, vd *v) {
    v[0] = col[3] + (col[1] * p[2] - col[2] * p[1]);
    v[1] = col[4] + (col[2] * p[0] - col[0] * p[2]);
    v[2] = col[5] + (col[0] * p[1] - col[1] * p[0]);
}

/* Write the n space-Jacobian columns in jac, turned into convention (JAC_SPACE, JAC_BODY,
 * JAC_WORLD) at the end pose cur, as each lane's (6, n) block of out (poekin.chain.
 * jacobian_from_world's arithmetic: world v + a x p, body R^T of the world rows). */
AI void jacobian_emit(const Pose *cur, int convention, const vd *jac, int n, double *out,
                      npy_intp stride, int lanes) {
    const vd *R = cur->R, *p = cur->t;
    for (int c = 0; c < n; ++c) {
        const vd *col = jac + 6 * c;
        vd J[6] = {col[0], col[1], col[2], col[3], col[4], col[5]};
        if (convention != JAC_SPACE) world_velocity(col, p, J + 3);
        if (convention == JAC_BODY) { /* R^T of both rows */
            vd W[6] = {J[0], J[1], J[2], J[3], J[4], J[5]};
            for (int h = 0; h < 2; ++h)
                for (int i = 0; i < 3; ++i)
                    J[3 * h + i] = (R[i] * W[3 * h] + R[3 + i] * W[3 * h + 1]) + R[6 + i] * W[3 * h + 2];
        }
        for (int l = 0; l < lanes; ++l)
            for (int r = 0; r < 6; ++r) out[l * stride + r * n + c] = J[r][l];
    }
}

/* Run the program on one block of LANES configurations, q transposed in qT; slots hold the
 * stored poses, ang the angles. huge: some |q| may give an angle beyond REDUCE_MAX. With out
 * NULL nothing is written (EMIT and JEMIT are skipped): the caller reads the state the
 * program ends in from *end and the Jacobian's space columns from jac (the IK solver). */
AI void run_ops(const Program *prog, Pose *restrict slots, const vd *restrict qT,
                Angle *restrict ang, vd *restrict jac, double *out, int form, int lanes,
                int huge, Pose *end) {
    const int size = out_size(prog, form);
    const npy_intp stride = (npy_intp)prog->n_out * size;
    Pose cur;
    if (end != NULL) /* programs start with IDENTITY or LOAD; the compiler cannot know it */
        for (int i = 0; i < 9; ++i) cur.R[i] = cur.t[i % 3] = (vd){0};
    for (int k = 0; k < 6 * prog->jac_cols; ++k) jac[k] = (vd){0}; /* columns add up */
    /* every angle's sin and cos first, two at a time: independent work whose latencies overlap */
    for (int k = 0; k < prog->n_angles; k += 2) {
        const AngleSource *src = prog->angles + k, *srcb = src + 1;
        vd ta = qT[src->qadr], tb = qT[srcb->qadr];
        if (!src->plain) ta = (ta * src->P[0] + src->P[1]) - src->P[2];
        if (!srcb->plain) tb = (tb * srcb->P[0] + srcb->P[1]) - srcb->P[2];
        vd sa, ca, sb, cb;
        sincos_fast(ta, &sa, &ca);
        sincos_fast(tb, &sb, &cb);
        if (huge) {
            sincos_fixup(ta, &sa, &ca);
            sincos_fixup(tb, &sb, &cb);
        }
        ang[k] = (Angle){ta, sa, ca};
        ang[k + 1] = (Angle){tb, sb, cb};
    }
    for (const Op *op = prog->ops, *end = prog->ops + prog->n_ops; op < end; ++op) {
        const int a = op->a, slot = op->slot;
        const double *P = op->P;
        vd Rj[9], tj[3];
        switch (op->code) {
            case OP_IDENTITY:
                for (int i = 0; i < 9; ++i) cur.R[i] = (vd){0} + ((i % 4 == 0) ? 1.0 : 0.0);
                for (int i = 0; i < 3; ++i) cur.t[i] = (vd){0};
                break;
            case OP_LOAD:
                copy_pose(&cur, slots + slot);
                break;
            case OP_STORE:
                copy_pose(slots + slot, &cur);
                break;
            case OP_CONST:
                compose_const(&cur, P, P + 9);
                break;
            case OP_TRANSLATE: /* compose's translation; R * I = R */
                for (int i = 0; i < 3; ++i)
                    cur.t[i] = cur.t[i] +
                               ((cur.R[3 * i] * P[0] + cur.R[3 * i + 1] * P[1]) + cur.R[3 * i + 2] * P[2]);
                break;
            case OP_SCREW: /* R = (I + s W) + c W2, c = 1 - cos q; p = (r - R r) + q u */
                rodrigues(P, P + 9, ang[slot].s, 1.0 - ang[slot].c, Rj);
                about_point(P + 18, Rj, tj);
                for (int i = 0; i < 3; ++i) tj[i] = tj[i] + ang[slot].th * P[21 + i];
                compose(&cur, Rj, tj);
                break;
            case OP_HINGE:
                rodrigues(P + 3, P + 12, ang[slot].s, 1.0 - ang[slot].c, Rj);
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
            /* one case per axis and pitch, each with literal k and pitch, so R stays in
             * registers */
            case OP_AXIS_X: axis_turn(&cur, 0, 0, ang + slot, P); break;
            case OP_AXIS_Y: axis_turn(&cur, 1, 0, ang + slot, P); break;
            case OP_AXIS_Z: axis_turn(&cur, 2, 0, ang + slot, P); break;
            case OP_AXIS_X_PITCH: axis_turn(&cur, 0, 1, ang + slot, P); break;
            case OP_AXIS_Y_PITCH: axis_turn(&cur, 1, 1, ang + slot, P); break;
            case OP_AXIS_Z_PITCH: axis_turn(&cur, 2, 1, ang + slot, P); break;
            case OP_JCOL: /* column slot: Ad(cur) [w; v] = [R w; p x R w + R v] */
                jacobian_column(&cur, P, jac + 6 * slot);
                break;
            case OP_JEMIT:
                if (out != NULL)
                    jacobian_emit(&cur, (int)P[0], jac, prog->jac_cols, out, stride, lanes);
                break;
            case OP_EMIT:
                if (out != NULL) emit(&cur, form, out + (npy_intp)slot * size, stride, lanes);
                break;
            default: /* Kernel_init took only the codes above */
                __builtin_unreachable();
        }
    }
    if (end != NULL) copy_pose(end, &cur);
}

AI void run_block(const Program *prog, const double *q, npy_intp n_rows,
                                double *out, int form, Pose *slots, vd *qT, Angle *ang,
                                vd *jac, int *bad) {
    const int nq = prog->nq;
    const int lanes = n_rows < LANES ? (int)n_rows : LANES;
    const double huge_q = prog->huge_q;
    /* transpose the block's q to qT[j][lane]; lanes past the end repeat the last row */
    const vl sign = (vl){0} + INT64_MAX;
    const vd limit = (vd){0} + huge_q;
    vl below = (vl){0} - 1; /* per lane: every |q| < huge_q (false for NaN and inf too) */
    const double *row[LANES];
    for (int l = 0; l < LANES; ++l) row[l] = q + (l < lanes ? l : lanes - 1) * nq;
    for (int j = 0; j < nq; ++j) {
        vd v;
        for (int l = 0; l < LANES; ++l) v[l] = row[l][j];
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
    run_ops(prog, slots, qT, ang, jac, out, form, lanes, !ok, NULL);
}

TARGET static void run_task(Task *task) {
    const Program *prog = task->prog;
    const npy_intp stride = (npy_intp)prog->n_out * out_size(prog, task->form);
    size_t n_slots = prog->n_slots, n_q = prog->nq, n_ang = prog->n_angles;
    size_t n_jac = 6 * (size_t)prog->jac_cols;
    size_t bytes =
        sizeof(Pose) * n_slots + sizeof(vd) * n_q + sizeof(Angle) * n_ang + sizeof(vd) * n_jac;
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
    vd *jac = (vd *)(base + sizeof(Pose) * n_slots + sizeof(vd) * n_q + sizeof(Angle) * n_ang);
    for (npy_intp i = task->lo; i < task->hi && !task->bad; i += LANES) {
        npy_intp rows = task->hi - i < LANES ? task->hi - i : LANES;
        run_block(prog, task->q + i * prog->nq, rows, task->out + i * stride, task->form, slots,
                  qT, ang, jac, &task->bad);
    }
    aligned_free(heap);
}

#include "_ik_core.h"

#undef vd
#undef vl
#undef vd_unaligned
#undef vselect
#undef sincos_fast
#undef sincos_fixup
#undef Pose
#undef copy_pose
#undef compose
#undef compose_const
#undef rodrigues
#undef about_point
#undef jacobian_column
#undef jacobian_emit
#undef world_velocity
#undef axis_turn
#undef quat_rotation
#undef rotation_quat
#undef pose_quat
#undef transpose8
#undef transpose4
#undef store_rows
#undef emit
#undef Angle
#undef run_ops
#undef run_block
#undef run_task
#undef GLUE
#undef GLUE_
