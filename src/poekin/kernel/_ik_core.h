/*
 * The inverse kinematics solver for one vector width: included at the end of _kernel_core.h,
 * with its LANES, TARGET and names (vd, Pose, run_ops, ...). The algorithm and the order of
 * every sum are those of poekin/ik/numerical.py, the NumPy reference, so both give the same
 * bits; the functions below name the reference's function they repeat.
 *
 * A group of G lanes (a power of two) solves one target at a time, and when the target is done
 * (solved, or its attempts spent) the group takes the next target of the batch, so the vector
 * stays full. G is 1 for batches of at least LANES targets: each lane runs its target's
 * attempts one after another. For fewer targets the lanes of a group run G attempts side by
 * side, in rounds (attempts rG .. rG + G - 1; with a start q0, attempt 0 alone in round 0, which
 * mostly succeeds, and attempts 1 + (r - 1)G .. rG in round r after it, so that the other lanes
 * cost it nothing: their random starts would block joints at their limits, and a blocked lane
 * makes the whole vector solve again), and commit them in attempt order: the answer is
 * the first successful attempt, its iterations those of every attempt up to it, as if they had
 * run one after another (solve_reference); without success, the least-cost iterate of all of
 * them, the earlier attempt's on a tie. A target's answer therefore depends only on its own
 * numbers (its random starts are keyed by its bits), never on G, its lane, its neighbours, the
 * thread or the width.
 */
#define IKState GLUE(IKState, LANES)
#define ik_state GLUE(ik_state, LANES)
#define ik_dot_rows GLUE(ik_dot_rows, LANES)
#define ik_cholesky_solve GLUE(ik_cholesky_solve, LANES)
#define ik_damped_step GLUE(ik_damped_step, LANES)
#define ik_damped_step_sized GLUE(ik_damped_step_sized, LANES)
#define ik_capped GLUE(ik_capped, LANES)
#define ik_wrapped GLUE(ik_wrapped, LANES)
#define ik_clamped GLUE(ik_clamped, LANES)
#define ik_step GLUE(ik_step, LANES)
#define ik_residual GLUE(ik_residual, LANES)
#define ik_finish GLUE(ik_finish, LANES)
#define ik_load GLUE(ik_load, LANES)
#define ik_attempt GLUE(ik_attempt, LANES)
#define ik_commit GLUE(ik_commit, LANES)
#define ik_run_task GLUE(ik_run_task, LANES)

typedef struct {
    /* n entries each, in the memory after the struct (ik_state) */
    vd *q;                              /* the iterate */
    vd *qn;                             /* the next one */
    vd *best_q;                         /* the least-cost iterate */
    vd *d, *v, *w, *fixed, *df, *v2, *w2;
    vl *blocked;
    Angle *ang;                         /* run_ops' angles (n rounded up to even) */
    vd *jac;                            /* the space Jacobian's columns (6 n) */
    vd *J[6];                           /* the residual's Jacobian, rows */
    vd *Jf[6];                          /* the same, blocked joints' columns zeroed */
    vd best_R[9], best_p[3], best_cost; /* the least-cost iterate's pose and cost */
    vd Rt[9], pt[3];                    /* the targets */
    /* per lane */
    npy_intp target[LANES]; /* -1: idle */
    uint64_t key[LANES]; /* the target's random starts' key, once a start needs it */
    int keyed[LANES];    /* key is set (per group: its first lane's) */
    int64_t attempt[LANES], it[LANES], stall[LANES];
    int64_t best_attempt[LANES]; /* the attempt of the lane's least-cost iterate */
    int running[LANES];          /* an attempt runs; else it has ended, or the round has none */
    int converged[LANES];        /* the attempt that ended succeeded */
    double stall_ref[LANES];
    /* per group: lanes [g G, g G + G) */
    int G;
    int64_t round[LANES], total[LANES];
} IKState;

/* An IKState for n joints with its arrays after it, in one aligned block: in `stack` (of
 * STACK_SCRATCH bytes) where it fits (no malloc per call: a one-target call's own cost, issue
 * 26), else on the heap, *heap then the block to free; NULL if out of memory. */
static IKState *ik_state(int n, unsigned char *stack, unsigned char **heap) {
    const size_t angles = (size_t)(n + 1) / 2 * 2, per = (size_t)n;
    const size_t head = (sizeof(IKState) + sizeof(vd) - 1) / sizeof(vd) * sizeof(vd);
    size_t bytes = head + sizeof(vd) * per * (10 + 1 + 6 + 12) + sizeof(Angle) * angles;
    *heap = bytes > STACK_SCRATCH ? aligned_malloc(bytes) : NULL;
    unsigned char *block = bytes > STACK_SCRATCH ? *heap : stack;
    if (block == NULL) return NULL;
    IKState *S = (IKState *)block;
    vd *next = (vd *)(block + head);
    vd **arrays[10] = {&S->q, &S->qn, &S->best_q, &S->d, &S->v, &S->w, &S->fixed, &S->df, &S->v2, &S->w2};
    for (int k = 0; k < 10; ++k, next += per) *arrays[k] = next;
    S->blocked = (vl *)next, next += per;
    S->jac = next, next += 6 * per;
    for (int k = 0; k < 6; ++k, next += per) S->J[k] = next;
    for (int k = 0; k < 6; ++k, next += per) S->Jf[k] = next;
    S->ang = (Angle *)next;
    return S;
}

/* sum over k < m of A[k][i] B[k][j], as the reference's _dot: the first product, then the
 * others added in order. */
AI vd ik_dot_rows(vd *const *A, int i, vd *const *B, int j, int m) {
    vd t = A[0][i] * B[0][j];
    for (int k = 1; k < m; ++k) t = t + A[k][i] * B[k][j];
    return t;
}

#ifndef IK_LDL_SOLVE
/* _cholesky_solve's body for a system of size s <= N: A x = b by L D L^T, the lower triangle
 * of A read, pivots below tiny taken as tiny (both sizes' functions: ik_cholesky_solve here,
 * ik_step_cholesky in _ik_step.h) */
#define IK_LDL_SOLVE(N)                                                                        \
    vd L[N][N], E[N][N], D[N], y[N];                                                           \
    const vd t0 = (vd){0} + tiny;                                                              \
    for (int j = 0; j < s; ++j) {                                                              \
        vd acc = A[j][j];                                                                      \
        for (int k = 0; k < j; ++k) acc = acc - E[j][k] * L[j][k];                             \
        D[j] = vselect(acc > tiny, acc, t0);                                                   \
        for (int i = j + 1; i < s; ++i) {                                                      \
            acc = A[i][j];                                                                     \
            for (int k = 0; k < j; ++k) acc = acc - E[i][k] * L[j][k];                         \
            E[i][j] = acc;                                                                     \
            L[i][j] = acc / D[j];                                                              \
        }                                                                                      \
    }                                                                                          \
    for (int i = 0; i < s; ++i) {                                                              \
        vd acc = b[i];                                                                         \
        for (int k = 0; k < i; ++k) acc = acc - L[i][k] * y[k];                                \
        y[i] = acc;                                                                            \
    }                                                                                          \
    for (int i = s - 1; i >= 0; --i) {                                                         \
        vd acc = y[i] / D[i];                                                                  \
        for (int k = i + 1; k < s; ++k) acc = acc - L[k][i] * x[k];                            \
        x[i] = acc;                                                                            \
    }
#endif

/* _cholesky_solve: A x = b for s <= 6 (IK_LDL_SOLVE). */
AI void ik_cholesky_solve(vd A[6][6], const vd *b, vd *x, int s, double tiny) { IK_LDL_SOLVE(6) }

/* damped_step: d = (J^T J + lam I)^-1 J^T r for n <= m, else J^T (J J^T + lam I)^-1 r. */
AI void ik_damped_step_sized(vd *const *J, const vd *r, vd lam, double tiny, int m, int n,
                             vd *d) {
    vd A[6][6], b[6], z[6];
    if (n <= m) {
        for (int i = 0; i < n; ++i)
            for (int j = 0; j <= i; ++j) A[i][j] = ik_dot_rows(J, i, J, j, m);
        for (int i = 0; i < n; ++i) A[i][i] = A[i][i] + lam;
        for (int i = 0; i < n; ++i) {
            vd t = J[0][i] * r[0];
            for (int k = 1; k < m; ++k) t = t + J[k][i] * r[k];
            b[i] = t;
        }
        ik_cholesky_solve(A, b, d, n, tiny);
        return;
    }
    for (int a = 0; a < m; ++a)
        for (int c = 0; c <= a; ++c) {
            vd t = J[a][0] * J[c][0];
            for (int i = 1; i < n; ++i) t = t + J[a][i] * J[c][i];
            A[a][c] = t;
        }
    for (int a = 0; a < m; ++a) A[a][a] = A[a][a] + lam;
    ik_cholesky_solve(A, r, z, m, tiny);
    for (int i = 0; i < n; ++i) {
        vd t = J[0][i] * z[0];
        for (int a = 1; a < m; ++a) t = t + J[a][i] * z[a];
        d[i] = t;
    }
}

/* ik_damped_step_sized with the usual sizes as constants, which the compiler unrolls and
 * schedules in part (the same operations in the same order: the same bits). */
AI void ik_damped_step(vd *const *J, const vd *r, vd lam, double tiny, int m, int n, vd *d) {
    if (m == 6 && n == 6)
        ik_damped_step_sized(J, r, lam, tiny, 6, 6, d);
    else if (m == 6 && n == 7)
        ik_damped_step_sized(J, r, lam, tiny, 6, 7, d);
    else
        ik_damped_step_sized(J, r, lam, tiny, m, n, d);
}

/* _capped: d scaled so that its largest entry is at most step_max in size. */
AI void ik_capped(vd *d, int n, double step_max) {
    const vl magnitude = (vl){0} + INT64_MAX;
    vd largest = (vd)((vl)d[0] & magnitude);
    for (int j = 1; j < n; ++j) {
        vd a = (vd)((vl)d[j] & magnitude);
        largest = vselect(largest >= a, largest, a);
    }
    const vd one = (vd){0} + 1.0;
    vd factor = vselect(largest > step_max, step_max / vselect(largest > 0, largest, one), one);
    for (int j = 0; j < n; ++j) d[j] = d[j] * factor;
}

/* wrapped: each value turned into its limits where whole turns help (ik_wrap), lanes already
 * inside untouched. */
AI void ik_wrapped(const IKModel *m, const vd *v, vd *w) {
    for (int j = 0; j < m->n; ++j) {
        const int flags = m->flags[j];
        const vd x = v[j];
        w[j] = x;
        if (!(flags & IK_REVOLUTE)) continue;
        vl inside = (flags & IK_CYCLIC) ? (x > -IK_PI) & (x <= IK_PI) : (x >= m->lo[j]) & (x <= m->hi[j]);
        for (int l = 0; l < LANES; ++l)
            if (!inside[l]) w[j][l] = ik_wrap(x[l], m->lo[j], m->hi[j], flags);
    }
}

/* numpy.minimum(numpy.maximum(x, lo), hi) */
AI vd ik_clamped(vd x, double lo, double hi) {
    vd a = vselect(x >= lo, x, (vd){0} + lo);
    return vselect(a <= hi, a, (vd){0} + hi);
}

/* step: the next iterate S->qn from S->q, the residual r (rows) and its Jacobian S->J. */
AI void ik_step(IKState *S, const IKModel *m, const IKOptions *o, const vd *r, vd cost, int rows) {
    const int n = m->n;
    vd lam = o->damping * cost + o->floor;
    lam = vselect(lam <= o->ceiling, lam, (vd){0} + o->ceiling);
    ik_damped_step(S->J, r, lam, o->floor, rows, n, S->d);
    ik_capped(S->d, n, o->step_max);
    for (int j = 0; j < n; ++j) S->v[j] = S->q[j] + S->d[j];
    ik_wrapped(m, S->v, S->w);
    vl anything = (vl){0};
    for (int j = 0; j < n; ++j) {
        S->blocked[j] = (S->w[j] < m->lo[j]) | (S->w[j] > m->hi[j]);
        anything |= S->blocked[j];
    }
    int some = 0;
    for (int l = 0; l < LANES; ++l) some |= anything[l] != 0;
    if (some) { /* the active set: blocked joints to their limit, the others solved again */
        const vd zero = {0};
        vd rf[6];
        for (int j = 0; j < n; ++j)
            S->fixed[j] = vselect(S->blocked[j], ik_clamped(S->v[j], m->lo[j], m->hi[j]) - S->q[j], zero);
        for (int k = 0; k < rows; ++k) {
            vd t = S->J[k][0] * S->fixed[0];
            for (int j = 1; j < n; ++j) t = t + S->J[k][j] * S->fixed[j];
            rf[k] = r[k] - t;
            for (int j = 0; j < n; ++j) S->Jf[k][j] = vselect(S->blocked[j], zero, S->J[k][j]);
        }
        ik_damped_step(S->Jf, rf, lam, o->floor, rows, n, S->df);
        for (int j = 0; j < n; ++j) S->df[j] = vselect(S->blocked[j], S->fixed[j], S->df[j]);
        ik_capped(S->df, n, o->step_max);
        for (int j = 0; j < n; ++j) S->v2[j] = S->q[j] + S->df[j];
        ik_wrapped(m, S->v2, S->w2);
        for (int j = 0; j < n; ++j) S->w[j] = vselect(anything, S->w2[j], S->w[j]);
    }
    for (int j = 0; j < n; ++j) S->qn[j] = ik_clamped(S->w[j], m->lo[j], m->hi[j]);
}

/* residual: r (rows), |r|^2, |e_p|^2, |e_o|^2 at the pose cur; the Jacobian's rows in S->J from
 * the space columns in S->jac and the quaternion of R_t R^T (jacobian_rows). */
AI vd ik_residual(IKState *S, const Pose *cur, const IKOptions *o, int n, vd *r, vd *ep2,
                  vd *eo2) {
    const vd *R = cur->R;
    vd ep[3], M[9], quat[4], eo[3];
    for (int i = 0; i < 3; ++i) ep[i] = S->pt[i] - cur->t[i];
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            M[3 * i + j] = (S->Rt[3 * i] * R[3 * j] + S->Rt[3 * i + 1] * R[3 * j + 1]) +
                           S->Rt[3 * i + 2] * R[3 * j + 2];
    rotation_quat(M, quat);
    for (int i = 0; i < 3; ++i) eo[i] = 2.0 * quat[1 + i];
    const double k = o->weight;
    int rows = 0;
    if (!o->position_only)
        for (int i = 0; i < 3; ++i) r[rows++] = k * eo[i];
    for (int i = 0; i < 3; ++i) r[rows++] = ep[i];
    vd cost = r[0] * r[0];
    for (int i = 1; i < rows; ++i) cost = cost + r[i] * r[i];
    *ep2 = (ep[0] * ep[0] + ep[1] * ep[1]) + ep[2] * ep[2];
    *eo2 = (eo[0] * eo[0] + eo[1] * eo[1]) + eo[2] * eo[2];
    const vd w = quat[0], *u = quat + 1;
    for (int j = 0; j < n; ++j) {
        const vd *a = S->jac + 6 * j;
        vd v[3];
        world_velocity(a, cur->t, v);
        int row = 0;
        if (!o->position_only) { /* k (w a + u x a): d e_o = -(w I + [u]) a dt */
            const vd ua[3] = {u[1] * a[2] - u[2] * a[1], u[2] * a[0] - u[0] * a[2],
                              u[0] * a[1] - u[1] * a[0]};
            for (int i = 0; i < 3; ++i) S->J[row++][j] = k * (w * a[i] + ua[i]);
        }
        for (int i = 0; i < 3; ++i) S->J[row++][j] = v[i];
    }
    return cost;
}

/* Lane l's target is done: its answer (the iterate if it converged, else its least-cost one),
 * the errors at it (errors), the success flag, the counts (of lane l's group, attempts up to
 * `last`). */
TARGET static void ik_finish(IKState *S, const IKTask *task, const Pose *cur, int l, int conv,
                             int64_t last) {
    const IKModel *m = task->model;
    const IKOptions *o = task->opt;
    const npy_intp t = S->target[l];
    double R[9], p[3], Rt[9], e[3], M[9];
    for (int k = 0; k < 9; ++k) R[k] = conv ? cur->R[k][l] : S->best_R[k][l];
    for (int i = 0; i < 3; ++i) p[i] = conv ? cur->t[i][l] : S->best_p[i][l];
    for (int k = 0; k < 9; ++k) Rt[k] = S->Rt[k][l];
    int inside = 1;
    double *q = task->q + t * m->n;
    for (int j = 0; j < m->n; ++j) {
        q[j] = conv ? S->q[j][l] : S->best_q[j][l];
        inside &= q[j] >= m->lo[j] && q[j] <= m->hi[j];
    }
    for (int i = 0; i < 3; ++i) e[i] = task->T[16 * t + 4 * i + 3] - p[i]; /* not the aimed-at */
    const double pos = ik_distance(e);
    double sq;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            M[3 * i + j] =
                (Rt[3 * i] * R[3 * j] + Rt[3 * i + 1] * R[3 * j + 1]) + Rt[3 * i + 2] * R[3 * j + 2];
    const double vee[3] = {(M[7] - M[5]) / 2, (M[2] - M[6]) / 2, (M[3] - M[1]) / 2};
    sq = (vee[0] * vee[0] + vee[1] * vee[1]) + vee[2] * vee[2];
    const double ori = atan2(sq > 0 ? sqrt(sq) : 0.0, (((M[0] + M[4]) + M[8]) - 1) / 2);
    task->pos_err[t] = pos;
    task->ori_err[t] = ori;
    task->success[t] =
        conv && inside && pos <= o->pos_tol && (o->position_only || ori <= o->ori_tol);
    task->iterations[t] = S->total[l / S->G];
    task->attempts[t] = last + 1;
}

/* Start attempt a of lane l's target: q0 brought into the limits for attempt 0 if given
 * (first_start), else the attempt's random start; a lane of a round with no attempt a (beyond
 * max_attempts) keeps its last iterate, whose cost it has seen, and does not run. */
TARGET static void ik_attempt(IKState *S, const IKTask *task, int l, int64_t a, const double *q0) {
    const IKModel *m = task->model;
    S->attempt[l] = a;
    S->it[l] = S->stall[l] = 0;
    S->stall_ref[l] = INFINITY;
    S->converged[l] = 0;
    S->running[l] = a < task->opt->max_attempts;
    if (!S->running[l]) return;
    const int first = l / S->G * S->G;
    if ((a > 0 || q0 == NULL) && !S->keyed[first]) { /* the key of the target's bits, once */
        const npy_intp t = S->target[l];
        const double *q0t = task->q0 != NULL ? task->q0 + m->n * t : NULL;
        const uint64_t key = ik_key(task->seed, task->T + 16 * t, q0t, m->n);
        for (int k = first; k < first + S->G; ++k) S->key[k] = key;
        S->keyed[first] = 1;
    }
    for (int j = 0; j < m->n; ++j)
        S->q[j][l] = a == 0 && q0 != NULL
                         ? ik_clamp(ik_wrap(q0[j], m->lo[j], m->hi[j], m->flags[j]), m->lo[j], m->hi[j])
                         : ik_start(m, S->key[l], a, j);
}

/* Give group g the batch's next target and its first round; 0 if there is none left (the
 * group's lanes idle on a harmless problem). */
TARGET static int ik_load(IKState *S, IKTask *task, int g) {
    const IKModel *m = task->model;
    const npy_intp t = __atomic_fetch_add(task->next, 1, __ATOMIC_RELAXED);
    const int n = m->n, G = S->G;
    if (t >= task->N) {
        for (int l = g * G; l < g * G + G; ++l) {
            S->target[l] = -1;
            S->running[l] = 0;
            for (int k = 0; k < 9; ++k) S->Rt[k][l] = (k % 4 == 0) ? 1.0 : 0.0;
            for (int i = 0; i < 3; ++i) S->pt[i][l] = 0.0;
            for (int j = 0; j < n; ++j) S->q[j][l] = m->base[j];
        }
        return 0;
    }
    const double *T = task->T + 16 * t;
    const double *q0 = task->q0 != NULL ? task->q0 + n * t : NULL;
    S->round[g] = S->total[g] = 0;
    S->keyed[g * G] = 0; /* the key is computed where a random start needs it (ik_attempt) */
    for (int l = g * G; l < g * G + G; ++l) {
        S->target[l] = t;
        double pt[3];
        ik_aimed(T, pt);
        for (int i = 0; i < 3; ++i) {
            for (int j = 0; j < 3; ++j) S->Rt[3 * i + j][l] = T[4 * i + j];
            S->pt[i][l] = pt[i];
        }
        S->best_cost[l] = INFINITY;
        S->best_attempt[l] = -1;
        /* with q0, the other lanes of round 0 have no attempt (the count's: none runs) */
        ik_attempt(S, task, l, q0 != NULL && l > g * G ? task->opt->max_attempts : l - g * G, q0);
    }
    for (int l = g * G + 1; q0 != NULL && l < g * G + G; ++l) /* a harmless iterate: lane g G's */
        for (int j = 0; j < n; ++j) S->q[j][l] = S->q[j][g * G];
    return 1;
}

/* Group g's round, committed in attempt order as far as its attempts have ended: done (1) at
 * the first success or when the last round fails, else the next round starts once this one
 * has ended (0). */
TARGET static int ik_commit(IKState *S, IKTask *task, const Pose *cur, int g) {
    const int G = S->G, first = g * G;
    const int64_t max_attempts = task->opt->max_attempts;
    int64_t total = S->total[g];
    for (int l = first; l < first + G; ++l) {
        const int64_t a = S->attempt[l];
        if (a >= max_attempts) break; /* the last round has no more attempts */
        if (S->running[l]) return 0;  /* wait for it: an earlier attempt decides first */
        total += S->it[l];
        if (S->converged[l]) {
            S->total[g] = total;
            ik_finish(S, task, cur, l, 1, a);
            return 1;
        }
    }
    S->total[g] = total;
    /* the next round's first attempt: rG, or 1 + (r - 1)G after a round 0 of q0 alone */
    const int64_t next = (S->round[g] + 1) * G + (task->q0 != NULL ? 1 - G : 0);
    if (next >= max_attempts) { /* the least-cost iterate of every lane, earlier attempt first */
        int best = first;
        for (int l = first + 1; l < first + G; ++l)
            if (S->best_attempt[l] >= 0 &&
                (S->best_cost[l] < S->best_cost[best] ||
                 (S->best_cost[l] == S->best_cost[best] && S->best_attempt[l] < S->best_attempt[best])))
                best = l;
        ik_finish(S, task, cur, best, 0, max_attempts - 1);
        return 1;
    }
    S->round[g] += 1;
    for (int l = first; l < first + G; ++l) ik_attempt(S, task, l, next + (l - first), NULL);
    return 0;
}

/* solve_reference's loop, LANES / G targets at a time, until the batch is done. */
TARGET static void ik_run_task(IKTask *task) {
    const IKModel *m = task->model;
    const IKOptions *o = task->opt;
    const int n = m->n, rows = o->position_only ? 3 : 6;
    _Alignas(64) unsigned char stack[STACK_SCRATCH];
    unsigned char *heap;
    IKState *S = ik_state(n, stack, &heap);
    if (S == NULL) {
        task->bad = -1;
        return;
    }
    const int G = task->group, groups = LANES / G;
    S->G = G;
    int active = 0;
    for (int g = 0; g < groups; ++g) active += ik_load(S, task, g);
    const vd huge_q = (vd){0} + m->prog->huge_q;
    const vl magnitude = (vl){0} + INT64_MAX;
    while (active > 0) {
        /* evaluate: the pose and the space columns, with the kernel's sin and cos */
        vl below = (vl){0} - 1;
        for (int j = 0; j < n; ++j) below &= (vd)((vl)S->q[j] & magnitude) < huge_q;
        int huge = 0;
        for (int l = 0; l < LANES; ++l) huge |= below[l] == 0;
        Pose cur;
        run_ops(m->prog, NULL, S->q, S->ang, S->jac, NULL, FORM_4X4, LANES, huge, &cur);
        vd r[6], ep2, eo2;
        const vd cost = ik_residual(S, &cur, o, n, r, &ep2, &eo2);
        /* a lane that does not run keeps an iterate it has seen (never strictly better), or has
         * none (round 0's other lanes with q0) */
        vl running;
        for (int l = 0; l < LANES; ++l) running[l] = S->running[l] ? -1 : 0;
        const vl better = (cost < S->best_cost) & running;
        S->best_cost = vselect(better, cost, S->best_cost);
        for (int j = 0; j < n; ++j) S->best_q[j] = vselect(better, S->q[j], S->best_q[j]);
        for (int k = 0; k < 9; ++k) S->best_R[k] = vselect(better, cur.R[k], S->best_R[k]);
        for (int i = 0; i < 3; ++i) S->best_p[i] = vselect(better, cur.t[i], S->best_p[i]);
        for (int l = 0; l < LANES; ++l)
            if (better[l]) S->best_attempt[l] = S->attempt[l];
        int ended = 0, going = 0;
        for (int l = 0; l < LANES; ++l) {
            if (!S->running[l]) continue;
            if (cost[l] < S->stall_ref[l] * o->stall_factor) {
                S->stall_ref[l] = cost[l];
                S->stall[l] = 0;
            } else {
                S->stall[l] += 1;
            }
            S->it[l] += 1;
            /* per lane: a vector mask kept across ik_step crashes GCC 12 (SSE2 kernel) */
            S->converged[l] =
                ep2[l] <= o->pos_tol2 && (o->position_only || eo2[l] <= o->ori_tol2);
            if (S->converged[l] || S->stall[l] >= o->stall_iterations || S->it[l] >= o->max_iterations) {
                S->running[l] = 0; /* the attempt has ended; q stays the iterate it ended at */
                ended = 1;
            } else {
                going = 1;
            }
        }
        if (going) { /* the step of the lanes that go on (none: no step, the same bits) */
            ik_step(S, m, o, r, cost, rows);
            for (int l = 0; l < LANES; ++l)
                if (S->running[l])
                    for (int j = 0; j < n; ++j) S->q[j][l] = S->qn[j][l];
        }
        if (!ended) continue;
        for (int g = 0; g < groups; ++g)
            if (S->target[g * G] >= 0 && ik_commit(S, task, &cur, g))
                active += ik_load(S, task, g) - 1;
    }
    aligned_free(heap);
}

#include "_ik_step.h" /* the differential step (poekin/ik/step.py) */

#undef IKState
#undef ik_state
#undef ik_dot_rows
#undef ik_cholesky_solve
#undef ik_damped_step
#undef ik_damped_step_sized
#undef ik_capped
#undef ik_wrapped
#undef ik_clamped
#undef ik_step
#undef ik_residual
#undef ik_finish
#undef ik_load
#undef ik_attempt
#undef ik_commit
#undef ik_run_task
