/*
 * The differential IK step of a chain for one vector width: the compiled twin of
 * poekin/ik/step.py (step_entries), included by _ik_core.h with its LANES, TARGET and names. The
 * residual and its Jacobian are the solver's (ik_residual); the active set repeats the
 * reference's rounds operation for operation and in the same order, LANES targets side by side,
 * so that both give the same bits. A lane whose step is done keeps it while the others run.
 */
#define ik_step_gram GLUE(ik_step_gram, LANES)
#define ik_step_primal GLUE(ik_step_primal, LANES)
#define ik_step_free GLUE(ik_step_free, LANES)
#define ik_step_dual GLUE(ik_step_dual, LANES)
#define ik_step_cholesky GLUE(ik_step_cholesky, LANES)
#define ik_step_block GLUE(ik_step_block, LANES)
#define ik_step_task GLUE(ik_step_task, LANES)
#define ik_vmax GLUE(ik_vmax, LANES)
#define ik_vmin GLUE(ik_vmin, LANES)
#define ik_lselect GLUE(ik_lselect, LANES)

/* numpy.maximum and numpy.minimum of two lanes' values (no NaN reaches them) */
AI vd ik_vmax(vd a, vd b) { return vselect(a >= b, a, b); }
AI vd ik_vmin(vd a, vd b) { return vselect(a <= b, a, b); }
/* numpy.where of masks */
AI vl ik_lselect(vl mask, vl a, vl b) { return (mask & a) | (~mask & b); }

/* _cholesky_solve for s <= IK_STEP_MAX_JOINTS (IK_LDL_SOLVE, _ik_core.h) */
AI void ik_step_cholesky(vd A[IK_STEP_MAX_JOINTS][IK_STEP_MAX_JOINTS], const vd *b, vd *x, int s,
                         double tiny) {
    IK_LDL_SOLVE(IK_STEP_MAX_JOINTS)
}

/* _gram: H = J^T J (both triangles) and g = J^T b, m rows */
AI void ik_step_gram(vd J[6][IK_STEP_MAX_JOINTS], const vd *b, int m, int n,
                     vd H[IK_STEP_MAX_JOINTS][IK_STEP_MAX_JOINTS], vd *g) {
    for (int i = 0; i < n; ++i) {
        for (int j = 0; j <= i; ++j) {
            vd t = J[0][i] * J[0][j];
            for (int k = 1; k < m; ++k) t = t + J[k][i] * J[k][j];
            H[i][j] = H[j][i] = t;
        }
        vd t = J[0][i] * b[0];
        for (int k = 1; k < m; ++k) t = t + J[k][i] * b[k];
        g[i] = t;
    }
}

/* _solve_free's primal system: H's free rows and columns plus lam, g_i - sum_j H_ij x_j over
 * the fixed j (at, the fixed joints' x, 0 elsewhere) */
AI void ik_step_primal(vd H[IK_STEP_MAX_JOINTS][IK_STEP_MAX_JOINTS], const vd *g, const vd *at,
                       const vl *fixed, double lam, double tiny, int n, vd *d) {
    vd A[IK_STEP_MAX_JOINTS][IK_STEP_MAX_JOINTS], rhs[IK_STEP_MAX_JOINTS];
    const vd zero = {0};
    for (int i = 0; i < n; ++i) {
        for (int j = 0; j < i; ++j) A[i][j] = vselect(fixed[i] | fixed[j], zero, H[i][j]);
        A[i][i] = vselect(fixed[i], zero, H[i][i]) + lam;
        vd t = H[i][0] * at[0];
        for (int j = 1; j < n; ++j) t = t + H[i][j] * at[j];
        rhs[i] = vselect(fixed[i], zero, g[i] - t);
    }
    ik_step_cholesky(A, rhs, d, n, tiny);
}

/* damped_step_dual: d = J^T z, (J J^T + lam I) z = r, m x m */
AI void ik_step_dual(vd J[6][IK_STEP_MAX_JOINTS], const vd *r, double lam, double tiny, int m,
                     int n, vd *d) {
    vd B[IK_STEP_MAX_JOINTS][IK_STEP_MAX_JOINTS], z[6];
    for (int a = 0; a < m; ++a)
        for (int c = 0; c <= a; ++c) {
            vd t = J[a][0] * J[c][0];
            for (int i = 1; i < n; ++i) t = t + J[a][i] * J[c][i];
            B[a][c] = t;
        }
    for (int a = 0; a < m; ++a) B[a][a] = B[a][a] + lam;
    ik_step_cholesky(B, r, z, m, tiny);
    for (int i = 0; i < n; ++i) {
        vd t = J[0][i] * z[0];
        for (int a = 1; a < m; ++a) t = t + J[a][i] * z[a];
        d[i] = t;
    }
}

/* _solve_free: the free joints' optimum with the fixed ones at x, for the lanes that take it (a
 * lane that is done keeps its step, one with every joint fixed takes x: the same bits) */
AI void ik_step_free(vd J[6][IK_STEP_MAX_JOINTS], const vd *b,
                     vd H[IK_STEP_MAX_JOINTS][IK_STEP_MAX_JOINTS], const vd *g, double lam,
                     const vd *x, const vl *fixed, vl done, int rows, int n, vd *target) {
    const vd zero = {0};
    vd at[IK_STEP_MAX_JOINTS], d[IK_STEP_MAX_JOINTS];
    for (int j = 0; j < n; ++j) {
        at[j] = vselect(fixed[j], x[j], zero);
        d[j] = zero;
    }
    vl free = (vl){0}; /* a mask is -1 where true */
    for (int j = 0; j < n; ++j) free = free - ~fixed[j];
    const vl wide = free > rows;
    int primal = 0, dual = 0;
    for (int l = 0; l < LANES; ++l) {
        if (done[l] || free[l] == 0) continue;
        if (n > rows && wide[l])
            dual = 1;
        else
            primal = 1;
    }
    if (primal) ik_step_primal(H, g, at, fixed, lam, IK_STEP_FLOOR, n, d);
    if (dual) {
        vd Jf[6][IK_STEP_MAX_JOINTS], bf[6], by_rows[IK_STEP_MAX_JOINTS];
        for (int k = 0; k < rows; ++k) {
            for (int j = 0; j < n; ++j) Jf[k][j] = vselect(fixed[j], zero, J[k][j]);
            vd t = J[k][0] * at[0];
            for (int j = 1; j < n; ++j) t = t + J[k][j] * at[j];
            bf[k] = b[k] - t;
        }
        ik_step_dual(Jf, bf, lam, IK_STEP_FLOOR, rows, n, by_rows);
        for (int j = 0; j < n; ++j) d[j] = vselect(wide, by_rows[j], d[j]);
    }
    for (int j = 0; j < n; ++j) target[j] = vselect(fixed[j], x[j], d[j]);
}

/* step_entries for the lanes of S (their q, Rt, pt loaded) with bounds lo, hi: x */
AI void ik_step_block(IKState *S, const IKModel *m, const IKOptions *o, const vd *lo,
                      const vd *hi, double gain, double lam, double release, int rounds, vd *x) {
    const int n = m->n, rows = o->position_only ? 3 : 6;
    const vl magnitude = (vl){0} + INT64_MAX;
    const vd huge_q = (vd){0} + m->prog->huge_q;
    vl below = (vl){0} - 1;
    for (int j = 0; j < n; ++j) below &= (vd)((vl)S->q[j] & magnitude) < huge_q;
    int huge = 0;
    for (int l = 0; l < LANES; ++l) huge |= below[l] == 0;
    Pose cur;
    run_ops(m->prog, NULL, S->q, S->ang, S->jac, NULL, FORM_4X4, LANES, huge, &cur);
    vd r[6], ep2, eo2, b[6];
    (void)ik_residual(S, &cur, o, n, r, &ep2, &eo2);
    vd J[6][IK_STEP_MAX_JOINTS], H[IK_STEP_MAX_JOINTS][IK_STEP_MAX_JOINTS], g[IK_STEP_MAX_JOINTS];
    for (int k = 0; k < rows; ++k)
        for (int j = 0; j < n; ++j) J[k][j] = S->J[k][j];
    for (int k = 0; k < rows; ++k) b[k] = gain * r[k];
    ik_step_gram(J, b, rows, n, H, g);
    const vd zero = {0}, one = (vd){0} + 1.0, two = (vd){0} + 2.0;
    const vl never = (vl){0};
    vd size_b = b[0] * b[0];
    for (int k = 1; k < rows; ++k) size_b = size_b + b[k] * b[k];
    for (int l = 0; l < LANES; ++l) size_b[l] = sqrt(size_b[l]);
    vd scale[IK_STEP_MAX_JOINTS], target[IK_STEP_MAX_JOINTS]; /* _Data.scale: |J_j| |b|, or 1 */
    vl pinned[IK_STEP_MAX_JOINTS], fixed[IK_STEP_MAX_JOINTS];
    for (int j = 0; j < n; ++j) {
        vd t = H[j][j];
        for (int l = 0; l < LANES; ++l) t[l] = sqrt(t[l]);
        t = t * size_b;
        scale[j] = vselect(t > 0.0, t, one);
        pinned[j] = lo[j] >= hi[j];
        x[j] = ik_vmin(ik_vmax(zero, lo[j]), hi[j]);
    }
    /* the first round: the free joints' optimum clamped into the box, each joint it cut fixed */
    ik_step_free(J, b, H, g, lam, x, pinned, never, rows, n, target);
    vl cut_any = never;
    for (int j = 0; j < n; ++j) {
        x[j] = ik_vmin(ik_vmax(target[j], lo[j]), hi[j]);
        const vl cut = ~pinned[j] & (x[j] != target[j]);
        fixed[j] = pinned[j] | cut;
        cut_any = cut_any | cut;
    }
    vl done = ~cut_any;
    for (int round = 0; round < rounds; ++round) {
        int all = 1;
        for (int l = 0; l < LANES; ++l) all &= done[l] != 0;
        if (all) break;
        ik_step_free(J, b, H, g, lam, x, fixed, done, rows, n, target);
        /* (1) toward the free joints' optimum, as far as the box allows */
        vd p[IK_STEP_MAX_JOINTS], alpha = one;
        vl block[IK_STEP_MAX_JOINTS];
        for (int j = 0; j < n; ++j) {
            p[j] = target[j] - x[j];
            block[j] = never;
        }
        for (int j = 0; j < n; ++j) {
            const vl down = p[j] < 0.0;
            const vd room = vselect(down, lo[j] - x[j], hi[j] - x[j]);
            const vl moving = ~fixed[j] & (p[j] != 0.0);
            const vd ratio = vselect(moving, room / vselect(moving, p[j], one), two);
            const vl first = ratio < alpha;
            for (int k = 0; k < n; ++k) block[k] = k == j ? first : block[k] & ~first;
            alpha = vselect(first, ratio, alpha);
        }
        const vl full = alpha >= 1.0;
        vd moved[IK_STEP_MAX_JOINTS];
        vl fixed_moved[IK_STEP_MAX_JOINTS];
        for (int j = 0; j < n; ++j) {
            const vd at = vselect(p[j] < 0.0, lo[j], hi[j]);
            const vd v = vselect(full, target[j], vselect(block[j], at, x[j] + alpha * p[j]));
            moved[j] = ik_vmin(ik_vmax(v, lo[j]), hi[j]);
            fixed_moved[j] = fixed[j] | (block[j] & ~full);
        }
        /* (2) where the move reached the optimum: the most negative multiplier's joint there
         * released */
        vd worst = (vd){0} + release;
        vl rel[IK_STEP_MAX_JOINTS];
        for (int j = 0; j < n; ++j) rel[j] = never;
        for (int j = 0; j < n; ++j) {
            vd t = H[j][0] * moved[0];
            for (int k = 1; k < n; ++k) t = t + H[j][k] * moved[k];
            const vd grad = (t - g[j]) + lam * moved[j];
            const vd mu = vselect(moved[j] <= lo[j], grad, -grad) / scale[j];
            const vl candidate = fixed_moved[j] & ~pinned[j] & (mu < worst);
            for (int k = 0; k < n; ++k) rel[k] = k == j ? candidate : rel[k] & ~candidate;
            worst = vselect(candidate, mu, worst);
        }
        vl released = rel[0];
        for (int j = 1; j < n; ++j) released = released | rel[j];
        for (int j = 0; j < n; ++j) {
            const vl new_fixed = fixed_moved[j] & ~(full & rel[j]);
            x[j] = vselect(done, x[j], moved[j]);
            fixed[j] = ik_lselect(done, fixed[j], new_fixed);
        }
        done = done | (full & ~released);
    }
}

/* The steps of targets [first, last): T (N, 4, 4) and q (N, n), the bounds from the limits and
 * each joint's reach (v dt: step.py's lo and hi), x (N, n) out */
TARGET static int ik_step_task(const IKModel *m, const IKOptions *o, const double *T,
                               const double *q, const double *reach, double gain, double lam,
                               double release, int rounds, npy_intp first, npy_intp last,
                               double *x) {
    const int n = m->n;
    _Alignas(64) unsigned char stack[STACK_SCRATCH];
    unsigned char *heap;
    IKState *S = ik_state(n, stack, &heap);
    if (S == NULL) return -1;
    for (npy_intp t0 = first; t0 < last; t0 += LANES) {
        vd lo[IK_STEP_MAX_JOINTS], hi[IK_STEP_MAX_JOINTS], vx[IK_STEP_MAX_JOINTS];
        for (int l = 0; l < LANES; ++l) {
            const npy_intp t = t0 + l < last ? t0 + l : -1;
            for (int k = 0; k < 9; ++k)
                S->Rt[k][l] = t < 0 ? (k % 4 == 0 ? 1.0 : 0.0) : T[16 * t + 4 * (k / 3) + k % 3];
            for (int i = 0; i < 3; ++i) S->pt[i][l] = t < 0 ? 0.0 : T[16 * t + 4 * i + 3];
            for (int j = 0; j < n; ++j) S->q[j][l] = t < 0 ? m->base[j] : q[n * t + j];
        }
        for (int j = 0; j < n; ++j) {
            const vd far = (vd){0} + reach[j], near = (vd){0} + (-reach[j]);
            lo[j] = ik_vmin(ik_vmax(m->lo[j] - S->q[j], near), far);
            hi[j] = ik_vmin(ik_vmax(m->hi[j] - S->q[j], near), far);
            for (int l = 0; l < LANES; ++l)
                if (t0 + l >= last) lo[j][l] = hi[j][l] = 0.0; /* idle: done in two rounds */
        }
        ik_step_block(S, m, o, lo, hi, gain, lam, release, rounds, vx);
        for (int l = 0; l < LANES && t0 + l < last; ++l)
            for (int j = 0; j < n; ++j) x[n * (t0 + l) + j] = vx[j][l];
    }
    aligned_free(heap);
    return 0;
}

#undef ik_step_gram
#undef ik_step_primal
#undef ik_step_free
#undef ik_step_dual
#undef ik_step_cholesky
#undef ik_step_block
#undef ik_step_task
#undef ik_vmax
#undef ik_vmin
#undef ik_lselect
