/*
 * The compiled twin of poekin.ik.analytic (the NumPy reference): every closed-form IK branch of
 * LANES targets side by side. _kernel.c includes it (as _ik_all.h) once per width after _kernel_core.h, with
 * LANES and TARGET defined; every name gets the width as a suffix (ik_all_task_8, ...).
 *
 * Each function below is the reference function of the same name (poekin.ik.subproblems,
 * poekin.ik.analytic) with the same operations in the same order, so that both give the same
 * bits but for atan2 (ours, fdlibm's polynomial: within an ulp or two of NumPy's) and what
 * follows from it (the whole turns that wrap_into_limits adds). A constant of the model is
 * broadcast to all lanes as it is (x - 0 keeps the sign of zero), so that an operation on two
 * constants, done in Python floats by the reference, is the same double operation here.
 */
#define GLUE_(a, b) a##_##b
#define GLUE(a, b) GLUE_(a, b)
#define vd GLUE(vd, LANES)
#define vl GLUE(vl, LANES)
#define vselect GLUE(vselect, LANES)
#define V3 GLUE(IkV3, LANES)
#define CS GLUE(IkCS, LANES)
#define Quad GLUE(IkQuad, LANES)
#define Shoulder GLUE(IkShoulder, LANES)
#define Branches GLUE(IkBranches, LANES)
#define bc GLUE(ik_bc, LANES)
#define bc3 GLUE(ik_bc3, LANES)
#define vsqrt GLUE(ik_sqrt, LANES)
#define dot GLUE(ik_dot, LANES)
#define cross GLUE(ik_cross, LANES)
#define add3 GLUE(ik_add, LANES)
#define sub3 GLUE(ik_sub, LANES)
#define unit GLUE(ik_unit, LANES)
#define rotate GLUE(ik_rotate, LANES)
#define sp1 GLUE(ik_sp1, LANES)
#define sp4 GLUE(ik_sp4, LANES)
#define sp3 GLUE(ik_sp3, LANES)
#define mat_vec GLUE(ik_mat_vec, LANES)
#define angle_plus GLUE(ik_plus, LANES)
#define angle_minus GLUE(ik_minus, LANES)
#define angle_half GLUE(ik_half, LANES)
#define pick GLUE(ik_pick, LANES)
#define atan2v GLUE(ik_atan2, LANES)
#define three_parallel GLUE(ik_three_parallel, LANES)
#define split_two_parallel GLUE(ik_two_parallel, LANES)
#define split_one_two_meet GLUE(ik_one_two_meet, LANES)
#define split_two_three_meet GLUE(ik_two_three_meet, LANES)
#define spherical GLUE(ik_spherical, LANES)
#define wrist_root GLUE(ik_wrist_root, LANES)
#define finish GLUE(ik_all_finish, LANES)
#define ik_block GLUE(ik_block, LANES)
#define ik_all_task GLUE(ik_all_task, LANES)

typedef struct {
    vd v[3];
} V3;

typedef struct {
    vd c, s; /* an angle's cosine and sine */
} CS;

typedef struct {
    CS root[2]; /* the + root, then the - root */
    vl exists, degenerate;
} Quad;

/* the first three joints' angles on two branch axes [i1][i2], and whether each exists */
typedef struct {
    CS a[3][2][2];
    vl exists[2][2];
} Shoulder;

/* the six angles of the 8 branches, [branch][joint], and whether each exists */
typedef struct {
    CS a[8][6];
    vl exists[8];
} Branches;

AI vd bc(double x) { return x - (vd){0}; }

AI V3 bc3(const double *x) { return (V3){{bc(x[0]), bc(x[1]), bc(x[2])}}; }

AI vd vsqrt(vd x) {
    for (int l = 0; l < LANES; ++l) x[l] = sqrt(x[l]);
    return x;
}

AI vd dot(V3 a, V3 b) { return (a.v[0] * b.v[0] + a.v[1] * b.v[1]) + a.v[2] * b.v[2]; }

AI V3 cross(V3 a, V3 b) {
    return (V3){{a.v[1] * b.v[2] - a.v[2] * b.v[1], a.v[2] * b.v[0] - a.v[0] * b.v[2],
                 a.v[0] * b.v[1] - a.v[1] * b.v[0]}};
}

AI V3 add3(V3 a, V3 b) { return (V3){{a.v[0] + b.v[0], a.v[1] + b.v[1], a.v[2] + b.v[2]}}; }

AI V3 sub3(V3 a, V3 b) { return (V3){{a.v[0] - b.v[0], a.v[1] - b.v[1], a.v[2] - b.v[2]}}; }

/* subproblems.unit */
AI CS unit(vd x, vd y) {
    const vd one = bc(1.0);
    vd r = vsqrt(x * x + y * y);
    vl zero = r == 0.0;
    vd safe = vselect(zero, one, r);
    return (CS){vselect(zero, one, x / safe), y / safe};
}

/* subproblems.rotate */
AI V3 rotate(V3 k, CS a, V3 p) {
    vd kp = dot(k, p);
    V3 kxp = cross(k, p), o;
    for (int i = 0; i < 3; ++i)
        o.v[i] = (kp * k.v[i] + a.c * (p.v[i] - kp * k.v[i])) + a.s * kxp.v[i];
    return o;
}

/* subproblems.sp1_cs */
AI CS sp1(V3 p1, V3 p2, V3 k) {
    V3 kxp1 = cross(k, p1), kxp2 = cross(k, p2);
    return unit(dot(kxp1, kxp2), dot(kxp1, p2));
}

/* subproblems.sp4_cs */
AI Quad sp4(V3 h, V3 p, V3 k, vd d, vd tol, vd tiny) {
    vd kp = dot(k, p), hk = dot(h, k);
    vd a = dot(h, p) - hk * kp;
    vd b = dot(h, cross(k, p));
    vd c = d - hk * kp;
    vd r2 = a * a + b * b;
    vd r = vsqrt(r2);
    vd e2 = r2 - c * c;
    vd e = vsqrt(vselect(e2 >= 0.0, e2, (vd){0})); /* np.maximum(e2, 0.0) */
    vd abs_c = vselect(c < 0.0, -c, c);
    Quad q;
    q.exists = abs_c - r <= tol;
    q.degenerate = r <= tiny;
    const vd zero = {0};
    q.root[0] = unit(vselect(q.degenerate, bc(1.0), a * c - b * e),
                     vselect(q.degenerate, zero, b * c + a * e));
    q.root[1] = unit(vselect(q.degenerate, bc(-1.0), a * c + b * e),
                     vselect(q.degenerate, zero, b * c - a * e));
    return q;
}

/* subproblems.sp3_cs */
AI Quad sp3(V3 p1, V3 p2, V3 k, vd dist2, vd tol, vd tiny) {
    vd d = ((dot(p1, p1) + dot(p2, p2)) - dist2) * 0.5;
    return sp4(p2, p1, k, d, tol, tiny);
}

/* _pose.mat_vec with a target's rotation R (row-major entries) */
AI V3 mat_vec(const vd *R, V3 v) {
    V3 o;
    for (int i = 0; i < 3; ++i)
        o.v[i] = (R[4 * i] * v.v[0] + R[4 * i + 1] * v.v[1]) + R[4 * i + 2] * v.v[2];
    return o;
}

/* analytic._plus, _minus, _half, _pick */
AI CS angle_plus(CS a, CS b, vd sign) {
    return (CS){a.c * b.c - sign * (a.s * b.s), a.s * b.c + sign * (a.c * b.s)};
}

AI CS angle_minus(CS a, CS b) { return (CS){a.c * b.c + a.s * b.s, a.s * b.c - a.c * b.s}; }

AI CS angle_half(CS a) {
    vd flip = vselect(a.s < 0.0, bc(-1.0), bc(1.0));
    vl front = a.c >= 0.0;
    return unit(vselect(front, 1.0 + a.c, flip * a.s), vselect(front, a.s, flip * (1.0 - a.c)));
}

AI CS pick(vl where, CS yes, CS no) {
    return (CS){vselect(where, yes.c, no.c), vselect(where, yes.s, no.s)};
}

/* atan2(y, x) for (x, y) not both 0: fdlibm's atan of t = min / max of |x|, |y| in [0, 1]
 * (its reduction to 0, 0.5 or 1 and its polynomial), then the octant. */
AI vd atan2v(vd y, vd x) {
    static const double aT[11] = {
        3.33333333333329318027e-01,  -1.99999999998764832476e-01, 1.42857142725034663711e-01,
        -1.11111104054623557880e-01, 9.09088713343650656196e-02,  -7.69187620504482999495e-02,
        6.66107313738753120669e-02,  -5.83357013379057348645e-02, 4.97687799461593236017e-02,
        -3.65315727442169155270e-02, 1.62858201153657823623e-02};
    const vd zero = {0};
    vd ax = vselect(x < 0.0, -x, x), ay = vselect(y < 0.0, -y, y);
    vl swap = ay > ax;
    vd t = vselect(swap, ax, ay) / vselect(swap, ay, ax);
    vl mid = t >= 0.4375, top = t >= 0.6875;
    vd num = vselect(top, t - 1.0, vselect(mid, t * 2.0 - 1.0, t));
    vd den = vselect(top, t + 1.0, vselect(mid, 2.0 + t, bc(1.0)));
    vd hi = vselect(top, bc(7.85398163397448278999e-01),
                    vselect(mid, bc(4.63647609000806093515e-01), zero));
    vd lo = vselect(top, bc(3.06161699786838301793e-17),
                    vselect(mid, bc(2.26987774529616870924e-17), zero));
    vd r = num / den;
    vd z = r * r, w = z * z;
    vd s1 = z * (aT[0] + w * (aT[2] + w * (aT[4] + w * (aT[6] + w * (aT[8] + w * aT[10])))));
    vd s2 = w * (aT[1] + w * (aT[3] + w * (aT[5] + w * (aT[7] + w * aT[9]))));
    vd a = hi - ((r * (s1 + s2) - lo) - r); /* atan(t) */
    const double pio2_hi = 1.57079632679489655800e+00, pio2_lo = 6.12323399573676603587e-17;
    const double pi_hi = 3.14159265358979311600e+00, pi_lo = 1.22464679914735317723e-16;
    a = vselect(swap, pio2_hi - (a - pio2_lo), a);
    a = vselect(x < 0.0, pi_hi - (a - pi_lo), a);
    vl negative = (vl)y < 0; /* the sign bit: atan2(-0, -1) = -pi */
    return vselect(negative, -a, a);
}

/* --- the splits: analytic._solve_three_parallel and the shoulders of _solve_spherical --- */

/* analytic._wrist for one root `first` of turn = sp4(h5, v, minus_axis, ...): q5, q6, sign
 * and phi. x0 is the normal x turned back through the joints before. */
AI void wrist_root(const IkWrist *W, V3 axis, V3 minus_axis, CS first, V3 v, V3 x0, CS *a5,
                   CS *a6, vd *sign, CS *phi) {
    V3 u = rotate(minus_axis, first, v); /* = rot(h5, q5) h6 */
    *a5 = sp1(bc3(W->h[5]), u, bc3(W->h[4]));
    V3 x = rotate(bc3(W->minus[4]), *a5, rotate(minus_axis, first, x0));
    *a6 = sp1(bc3(W->x6), x, bc3(W->h[5]));
    *sign = vselect(dot(axis, u) < 0.0, bc(-1.0), bc(1.0));
    *phi = angle_plus(first, *a6, *sign);
}

AI void three_parallel(const IkThreeParallel *P, const vd *T, Branches *out) {
    const IkWrist *W = &P->w;
    const V3 h = bc3(P->h), minus_h = bc3(P->minus_h), h3 = bc3(P->h3);
    const V3 minus_h1 = bc3(W->minus[0]), r1 = bc3(P->r1), r2 = bc3(P->r2);
    const V3 c56_r4 = bc3(P->c56_r4), p43 = bc3(P->p43), p23 = bc3(P->p23), p32 = bc3(P->p32);
    const V3 p = {{T[3], T[7], T[11]}};
    const vd sign3 = bc(P->sign3), sign4 = bc(P->sign4);
    V3 y1 = sub3(add3(mat_vec(T, bc3(P->c56_end)), p), r1);
    Quad shoulder = sp4(h, y1, minus_h1, bc(P->d1), bc(P->tol), bc(P->tiny));
    V3 Rh6 = mat_vec(T, bc3(W->h6_end)), Rx6 = mat_vec(T, bc3(W->x6_end));
    for (int i1 = 0; i1 < 2; ++i1) {
        CS a1 = shoulder.root[i1];
        V3 v = rotate(minus_h1, a1, Rh6);
        V3 x1 = rotate(minus_h1, a1, Rx6);
        Quad turn = sp4(bc3(W->h[4]), v, minus_h, bc(W->d56), bc(W->tol), bc(W->tiny));
        V3 back = add3(rotate(minus_h1, a1, y1), r1);
        CS fold = sp1(c56_r4, sub3(back, r2), h);
        for (int i2 = 0; i2 < 2; ++i2) {
            CS theta = turn.root[i2], a5, a6, phi;
            vd sign;
            wrist_root(W, h, minus_h, theta, v, x1, &a5, &a6, &sign, &phi);
            CS ends = i2 == 0 ? (CS){fold.c * 1.0, fold.s * 1.0} : (CS){fold.c * -1.0, fold.s * -1.0};
            theta = pick(turn.degenerate, ends, theta);
            CS rest = angle_minus(phi, theta);
            a6 = pick(turn.degenerate, (CS){rest.c, sign * rest.s}, a6);
            V3 zr = sub3(sub3(back, rotate(h, theta, c56_r4)), r2);
            Quad elbow = sp3(p43, p23, h3, dot(zr, zr), bc(P->tol2), bc(P->tiny2));
            for (int i3 = 0; i3 < 2; ++i3) {
                CS a3 = elbow.root[i3];
                CS a2 = sp1(add3(p32, rotate(h3, a3, p43)), zr, h);
                vd c23 = a2.c * a3.c - sign3 * (a2.s * a3.s);
                vd s23 = a2.s * a3.c + sign3 * (a2.c * a3.s);
                CS a4 = {theta.c * c23 + theta.s * s23, sign4 * (theta.s * c23 - theta.c * s23)};
                const int b = 4 * i1 + 2 * i2 + i3;
                CS *a = out->a[b];
                a[0] = a1, a[1] = a2, a[2] = a3, a[3] = a4, a[4] = a5, a[5] = a6;
                out->exists[b] = shoulder.exists & turn.exists & elbow.exists;
            }
        }
    }
}

AI void split_two_parallel(const IkTwoParallel *P, V3 y, Shoulder *out) {
    const V3 h2 = bc3(P->h2), h3 = bc3(P->h3), minus_h1 = bc3(P->minus_h1), r1 = bc3(P->r1);
    const V3 r2 = bc3(P->r2), pw3 = bc3(P->pw3), p23 = bc3(P->p23), p32 = bc3(P->p32);
    V3 y1 = sub3(y, r1);
    Quad shoulder = sp4(h2, y1, minus_h1, bc(P->d1), bc(P->tol), bc(P->tiny));
    for (int i1 = 0; i1 < 2; ++i1) {
        V3 zr = sub3(add3(rotate(minus_h1, shoulder.root[i1], y1), r1), r2);
        Quad elbow = sp3(pw3, p23, h3, dot(zr, zr), bc(P->tol2), bc(P->tiny2));
        for (int i2 = 0; i2 < 2; ++i2) {
            out->a[0][i1][i2] = shoulder.root[i1];
            out->a[1][i1][i2] = sp1(add3(p32, rotate(h3, elbow.root[i2], pw3)), zr, h2);
            out->a[2][i1][i2] = elbow.root[i2];
            out->exists[i1][i2] = shoulder.exists & elbow.exists;
        }
    }
}

AI void split_one_two_meet(const IkOneTwoMeet *P, V3 y, Shoulder *out) {
    const V3 h2 = bc3(P->h2), h3 = bc3(P->h3), minus_h1 = bc3(P->minus_h1), c = bc3(P->c);
    const V3 pw3 = bc3(P->pw3), pc3 = bc3(P->pc3), p3c = bc3(P->p3c);
    V3 yc = sub3(y, c);
    Quad elbow = sp3(pw3, pc3, h3, dot(yc, yc), bc(P->tol2), bc(P->tiny2));
    for (int i1 = 0; i1 < 2; ++i1) {
        V3 xc = add3(p3c, rotate(h3, elbow.root[i1], pw3));
        Quad shoulder = sp4(h2, yc, minus_h1, dot(h2, xc), bc(P->tol), bc(P->tiny));
        for (int i2 = 0; i2 < 2; ++i2) {
            out->a[0][i1][i2] = shoulder.root[i2];
            out->a[1][i1][i2] = sp1(xc, rotate(minus_h1, shoulder.root[i2], yc), h2);
            out->a[2][i1][i2] = elbow.root[i1];
            out->exists[i1][i2] = elbow.exists & shoulder.exists;
        }
    }
}

AI void split_two_three_meet(const IkTwoThreeMeet *P, V3 y, Shoulder *out) {
    const V3 h3 = bc3(P->h3), minus_h1 = bc3(P->minus_h1), minus_h2 = bc3(P->minus_h2);
    const V3 r1 = bc3(P->r1), pc1 = bc3(P->pc1), pwc = bc3(P->pwc), c = bc3(P->c);
    V3 y1 = sub3(y, r1);
    Quad shoulder = sp3(y1, pc1, minus_h1, bc(P->dist2), bc(P->tol2), bc(P->tiny2));
    for (int i1 = 0; i1 < 2; ++i1) {
        V3 zc = sub3(add3(rotate(minus_h1, shoulder.root[i1], y1), r1), c);
        Quad upper = sp4(h3, zc, minus_h2, bc(P->d3), bc(P->tol), bc(P->tiny));
        for (int i2 = 0; i2 < 2; ++i2) {
            out->a[0][i1][i2] = shoulder.root[i1];
            out->a[1][i1][i2] = upper.root[i2];
            out->a[2][i1][i2] = sp1(pwc, rotate(minus_h2, upper.root[i2], zc), h3);
            out->exists[i1][i2] = shoulder.exists & upper.exists;
        }
    }
}

AI void spherical(const IkSpherical *P, int kind, const vd *T, Branches *out) {
    const IkWrist *W = &P->w;
    V3 h[6], m[6];
    for (int j = 0; j < 6; ++j) h[j] = bc3(W->h[j]), m[j] = bc3(W->minus[j]);
    const V3 p = {{T[3], T[7], T[11]}};
    V3 y = add3(mat_vec(T, bc3(P->pw_end)), p);
    Shoulder first;
    if (kind == IK_TWO_PARALLEL)
        split_two_parallel(&P->s.two_parallel, y, &first);
    else if (kind == IK_ONE_TWO_MEET)
        split_one_two_meet(&P->s.one_two_meet, y, &first);
    else
        split_two_three_meet(&P->s.two_three_meet, y, &first);
    V3 Rh6 = mat_vec(T, bc3(W->h6_end)), Rx6 = mat_vec(T, bc3(W->x6_end));
    for (int i1 = 0; i1 < 2; ++i1) {
        for (int i2 = 0; i2 < 2; ++i2) {
            CS a1 = first.a[0][i1][i2], a2 = first.a[1][i1][i2], a3 = first.a[2][i1][i2];
            V3 v = rotate(m[2], a3, rotate(m[1], a2, rotate(m[0], a1, Rh6)));
            V3 x0 = rotate(m[2], a3, rotate(m[1], a2, rotate(m[0], a1, Rx6)));
            Quad turn = sp4(h[4], v, m[3], bc(W->d56), bc(W->tol), bc(W->tiny));
            for (int i3 = 0; i3 < 2; ++i3) {
                CS a4 = turn.root[i3], a5, a6, phi;
                vd sign;
                wrist_root(W, h[3], m[3], a4, v, x0, &a5, &a6, &sign, &phi);
                CS hf = angle_half(phi);
                CS on6 = i3 == 0 ? hf : phi;
                a4 = pick(turn.degenerate, i3 == 0 ? hf : (CS){bc(1.0), bc(0.0)}, a4);
                a6 = pick(turn.degenerate, (CS){on6.c, sign * on6.s}, a6);
                const int b = 4 * i1 + 2 * i2 + i3;
                CS *a = out->a[b];
                a[0] = a1, a[1] = a2, a[2] = a3, a[3] = a4, a[4] = a5, a[5] = a6;
                out->exists[b] = first.exists[i1][i2] & turn.exists;
            }
        }
    }
}

/* The angles of a block into its rows of q (n, 8, 6) and valid (n, 8): atan2, then
 * ik._angles.wrap_into_limits and within_limits. An angle that several branches share (the
 * reference's broadcast axes: IK_SHARED) is computed once. A joint with finite limits whose
 * angles are all inside them (the usual case) is settled in vectors; the others lane by lane. */
AI void finish(const Branches *br, int kind, const double *limits, int lanes, double *q,
               uint8_t *valid) {
    vd angle[8][6];
    for (int b = 0; b < 8; ++b)
        for (int j = 0; j < 6; ++j) {
            const int from = b & ~IK_SHARED[kind][j];
            angle[b][j] = from == b ? atan2v(br->a[b][j].s, br->a[b][j].c) : angle[from][j];
        }
    for (int b = 0; b < 8; ++b) {
        vl inside_all = br->exists[b];
        for (int j = 0; j < 6; ++j) {
            const double lo = limits[2 * j], hi = limits[2 * j + 1];
            vd v = angle[b][j];
            vl inside = (v >= lo) & (v <= hi);
            int all_inside = isfinite(lo) && isfinite(hi);
            for (int l = 0; l < LANES; ++l) all_inside &= inside[l] != 0;
            if (!all_inside) {
                for (int l = 0; l < LANES; ++l) v[l] = ik_wrap(v[l], lo, hi, ik_revolute_flags(lo, hi));
                inside = (v >= lo) & (v <= hi);
                angle[b][j] = v;
            }
            inside_all &= inside;
        }
        for (int l = 0; l < lanes; ++l) {
            double *row = q + ((npy_intp)l * 8 + b) * 6;
            for (int j = 0; j < 6; ++j) row[j] = angle[b][j][l];
            valid[(npy_intp)l * 8 + b] = (uint8_t)(inside_all[l] != 0);
        }
    }
}

/* One block of LANES targets T (n, 16), rows past the end repeating the last. */
AI void ik_block(const IkAllTask *task, npy_intp i) {
    const int lanes = task->hi - i < LANES ? (int)(task->hi - i) : LANES;
    vd T[16];
    for (int e = 0; e < 16; ++e) {
        vd v;
        for (int l = 0; l < LANES; ++l) v[l] = task->T[(i + (l < lanes ? l : lanes - 1)) * 16 + e];
        T[e] = v;
    }
    Branches br;
    if (task->kind == IK_THREE_PARALLEL)
        three_parallel((const IkThreeParallel *)task->params, T, &br);
    else
        spherical((const IkSpherical *)task->params, task->kind, T, &br);
    finish(&br, task->kind, task->limits, lanes, task->q + i * 48, task->valid + i * 8);
}

TARGET static void ik_all_task(IkAllTask *task) {
    for (npy_intp i = task->lo; i < task->hi; i += LANES) ik_block(task, i);
}

#undef vd
#undef vl
#undef vselect
#undef V3
#undef CS
#undef Quad
#undef Shoulder
#undef Branches
#undef bc
#undef bc3
#undef vsqrt
#undef dot
#undef cross
#undef add3
#undef sub3
#undef unit
#undef rotate
#undef sp1
#undef sp4
#undef sp3
#undef mat_vec
#undef angle_plus
#undef angle_minus
#undef angle_half
#undef pick
#undef atan2v
#undef three_parallel
#undef split_two_parallel
#undef split_one_two_meet
#undef split_two_three_meet
#undef spherical
#undef wrist_root
#undef finish
#undef ik_block
#undef ik_all_task
#undef GLUE
#undef GLUE_
