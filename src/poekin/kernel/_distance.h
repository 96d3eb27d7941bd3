/*
 * Signed distances and witness points of two convex shapes: the compiled twin of
 * poekin/collision/primitives.py (the closed forms) and poekin/collision/gjk.py (GJK, EPA and
 * the dispatch of gjk.distance), included by _kernel.c. Scalar C, one pair at a time: GJK's
 * rounds and EPA's polytope depend on the pair, and a pair costs a microsecond or two.
 *
 * Every function repeats its NumPy reference operation for operation and in the same order
 * (the reference writes its dot products, cross products, norms and matrix-vector products
 * out entry by entry for this), so that both give the same bits; numpy.where is ?:,
 * numpy.maximum (minimum) keeps its first argument on a tie, argmin and argmax the first
 * extreme. Shapes are MuJoCo's geom types and sizes: a pose (4x4, row-major), sizes (3) or a
 * mesh's vertices.
 */

enum {
    DG_PLANE = 0,
    DG_SPHERE = 2,
    DG_CAPSULE = 3,
    DG_ELLIPSOID = 4,
    DG_CYLINDER = 5,
    DG_BOX = 6,
    DG_MESH = 7,
};

/* primitives._TINY and primitives._PARALLEL */
#define DG_TINY 1e-30
#define DG_PARALLEL_EPS 1e-14

/* gjk.gjk's options, and closed: 1 for gjk.distance (the closed forms where there is one), 0
 * for gjk.gjk (GJK whatever the kinds; a plane only against a mesh) */
typedef struct {
    double tol, epa_tol;
    int max_iter, epa_faces, depth, closed;
} DgOptions;

/* One shape: its kind, its frame, its sizes or vertices, and the radius around its core
 * (gjk._Shape). */
typedef struct {
    int kind;
    const double *T; /* 4x4 row-major */
    const double *size;
    const double *verts; /* a mesh's nverts vertices (3 each) */
    npy_intp nverts;
    double radius;
} DgShape;

/* EPA's polytope, grown as needed; one per thread. */
typedef struct {
    double (*verts)[3], (*va)[3], (*vb)[3];
    int (*faces)[3];
    double (*normals)[3];
    double *dists;
    int (*adj)[3][2];
    char *alive;
    int (*horizon)[2];
    int (*edges)[4]; /* _link's table: u, v, face, edge */
    int n_verts, cap_verts, n_faces, cap_faces, n_horizon, cap_horizon;
    int failed; /* out of memory */
} DgWork;

static inline double dg_dot(const double *a, const double *b) {
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
static inline void dg_cross(const double *a, const double *b, double *out) {
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}
static inline void dg_sub(const double *a, const double *b, double *out) {
    for (int i = 0; i < 3; ++i) out[i] = a[i] - b[i];
}
static inline double dg_max(double a, double b) { return a >= b ? a : b; }
static inline double dg_min(double a, double b) { return a <= b ? a : b; }
static inline double dg_clip(double x, double lo, double hi) { return dg_min(dg_max(x, lo), hi); }
static inline double dg_sign(double x) { return x >= 0 ? 1.0 : -1.0; }
/* a pose's origin, column j of its rotation, R^T v and R v */
static inline void dg_origin(const double *T, double *p) {
    p[0] = T[3], p[1] = T[7], p[2] = T[11];
}
static inline void dg_column(const double *T, int j, double *c) {
    c[0] = T[j], c[1] = T[4 + j], c[2] = T[8 + j];
}
static inline void dg_to_local(const double *T, const double *v, double *out) {
    for (int i = 0; i < 3; ++i) out[i] = T[i] * v[0] + T[4 + i] * v[1] + T[8 + i] * v[2];
}
static inline void dg_to_world(const double *T, const double *v, double *out) {
    for (int i = 0; i < 3; ++i) out[i] = T[4 * i] * v[0] + T[4 * i + 1] * v[1] + T[4 * i + 2] * v[2];
}

/* ------------------------------------------------------------------------------------------ */
/* the closed forms (primitives.py) */

/* _unit: v / |v| and |v|, fallback where v is (nearly) zero */
static inline double dg_unit(const double *v, const double *fallback, double *u) {
    double s = dg_dot(v, v);
    int ok = s > DG_TINY;
    double n = sqrt(ok ? s : 1.0);
    for (int i = 0; i < 3; ++i) u[i] = ok ? v[i] / n : fallback[i];
    return ok ? n : 0.0;
}

static const double DG_X[3] = {1.0, 0.0, 0.0}, DG_Z[3] = {0.0, 0.0, 1.0},
                    DG_ZERO[3] = {0.0, 0.0, 0.0};

/* _inflated: the cores' closest points a and b inflated by r1 and r2 */
static void dg_inflated(const double *a, const double *b, double r1, double r2, double *dist,
                        double *pts) {
    double ab[3], n[3];
    dg_sub(b, a, ab);
    double length = dg_unit(ab, DG_Z, n);
    *dist = length - r1 - r2;
    for (int i = 0; i < 3; ++i) {
        pts[i] = a[i] + r1 * n[i];
        pts[3 + i] = b[i] - r2 * n[i];
    }
}

static void dg_sphere_sphere(const DgShape *A, const DgShape *B, double *dist, double *pts) {
    double c1[3], c2[3];
    dg_origin(A->T, c1);
    dg_origin(B->T, c2);
    dg_inflated(c1, c2, A->size[0], B->size[0], dist, pts);
}

static void dg_sphere_capsule(const DgShape *A, const DgShape *B, double *dist, double *pts) {
    double c[3], p[3], u[3], cp[3], b[3];
    dg_origin(A->T, c);
    dg_origin(B->T, p);
    dg_column(B->T, 2, u);
    double h = B->size[1];
    dg_sub(c, p, cp);
    double t = dg_clip(dg_dot(cp, u), -h, h);
    for (int i = 0; i < 3; ++i) b[i] = p[i] + t * u[i];
    dg_inflated(c, b, A->size[0], B->size[0], dist, pts);
}

/* _segments: the closest points of two segments (Ericson's clamped solution) */
static void dg_segments(const double *c1, const double *u, double h1, const double *c2,
                        const double *v, double h2, double *a, double *b) {
    double w[3];
    dg_sub(c1, c2, w);
    double bb = dg_dot(u, v), c = dg_dot(u, w), f = dg_dot(v, w);
    double denom = 1.0 - bb * bb;
    int parallel = denom < DG_PARALLEL_EPS;
    double s = parallel ? 0.0 : (bb * f - c) / denom;
    s = dg_clip(s, -h1, h1);
    double t = bb * s + f;
    double tc = dg_clip(t, -h2, h2);
    s = t == tc ? s : dg_clip(bb * tc - c, -h1, h1);
    for (int i = 0; i < 3; ++i) {
        a[i] = c1[i] + s * u[i];
        b[i] = c2[i] + tc * v[i];
    }
}

static void dg_capsule_capsule(const DgShape *A, const DgShape *B, double *dist, double *pts) {
    double p1[3], p2[3], u[3], v[3], a[3], b[3];
    dg_origin(A->T, p1);
    dg_origin(B->T, p2);
    dg_column(A->T, 2, u);
    dg_column(B->T, 2, v);
    dg_segments(p1, u, A->size[1], p2, v, B->size[1], a, b);
    dg_inflated(a, b, A->size[0], B->size[0], dist, pts);
}

/* the sphere A against the solid B, given the centre's signed distance sd to B and B's local
 * witness point and outward normal */
static void dg_sphere_solid(const DgShape *A, const DgShape *B, double sd, const double *point,
                            const double *normal, double *dist, double *pts) {
    double c[3], p[3], n[3], wp[3];
    dg_origin(A->T, c);
    dg_origin(B->T, p);
    double r = A->size[0];
    dg_to_world(B->T, normal, n);
    dg_to_world(B->T, point, wp);
    *dist = sd - r;
    for (int i = 0; i < 3; ++i) {
        pts[i] = c[i] - r * n[i];
        pts[3 + i] = p[i] + wp[i];
    }
}

static void dg_sphere_box(const DgShape *A, const DgShape *B, double *dist, double *pts) {
    double c[3], p[3], cp[3], q[3];
    dg_origin(A->T, c);
    dg_origin(B->T, p);
    dg_sub(c, p, cp);
    dg_to_local(B->T, cp, q);
    const double *h = B->size;
    /* _point_box */
    double clamped[3], gap[3], margin[3], in_normal[3], in_point[3];
    for (int i = 0; i < 3; ++i) {
        clamped[i] = dg_clip(q[i], -h[i], h[i]);
        gap[i] = q[i] - clamped[i];
        margin[i] = h[i] - fabs(q[i]);
    }
    int outside = dg_dot(gap, gap) > 0.0;
    int face = 0;
    for (int i = 1; i < 3; ++i)
        if (margin[i] < margin[face]) face = i;
    for (int i = 0; i < 3; ++i) {
        double sign = q[i] >= 0 ? 1.0 : -1.0;
        in_normal[i] = i == face ? sign : 0.0;
        in_point[i] = i == face ? sign * h[i] : q[i];
    }
    double depth = margin[face];
    double n_out[3];
    double length = dg_unit(gap, in_normal, n_out);
    double sd = outside ? length : -depth;
    dg_sphere_solid(A, B, sd, outside ? clamped : in_point, outside ? n_out : in_normal, dist,
                    pts);
}

static void dg_sphere_cylinder(const DgShape *A, const DgShape *B, double *dist, double *pts) {
    double c[3], p[3], cp[3], q[3];
    dg_origin(A->T, c);
    dg_origin(B->T, p);
    dg_sub(c, p, cp);
    dg_to_local(B->T, cp, q);
    double rc = B->size[0], h = B->size[1];
    double flat[3] = {q[0], q[1], 0.0}, radial[3];
    double rho = dg_unit(flat, DG_X, radial);
    double z = q[2];
    double sz = z >= 0 ? 1.0 : -1.0;
    double d_rho = rho - rc, d_z = fabs(z) - h;
    double rho_c = dg_min(rho, rc), z_c = dg_clip(z, -h, h);
    double near[3] = {radial[0] * rho_c + 0.0, radial[1] * rho_c + 0.0, radial[2] * rho_c + z_c};
    double gap[3];
    dg_sub(q, near, gap);
    int outside = (d_rho > 0) | (d_z > 0);
    int cap = d_z >= d_rho;
    double axis_z[3] = {0.0, 0.0, sz};
    double in_point[3];
    if (cap) {
        in_point[0] = q[0], in_point[1] = q[1], in_point[2] = sz * h;
    } else {
        in_point[0] = radial[0] * rc + 0.0;
        in_point[1] = radial[1] * rc + 0.0;
        in_point[2] = radial[2] * rc + z;
    }
    const double *in_normal = cap ? axis_z : radial;
    double n_out[3];
    double length = dg_unit(gap, in_normal, n_out);
    double sd = outside ? length : dg_max(d_rho, d_z);
    dg_sphere_solid(A, B, sd, outside ? near : in_point, outside ? n_out : in_normal, dist, pts);
}

/* _on_plane: the plane P against the shape whose lowest point is `lowest`, inflated by radius
 * (has_radius 0: none) */
static void dg_on_plane(const double *P, const double *lowest, int has_radius, double radius,
                        double *dist, double *pts) {
    double o[3], n[3], lo[3];
    dg_origin(P, o);
    dg_column(P, 2, n);
    dg_sub(lowest, o, lo);
    double height = dg_dot(lo, n);
    for (int i = 0; i < 3; ++i) {
        pts[i] = lowest[i] - height * n[i];
        pts[3 + i] = has_radius ? lowest[i] - radius * n[i] : lowest[i];
    }
    *dist = has_radius ? height - radius : height;
}

/* the plane (A's pose) against a primitive B */
static void dg_plane_shape(const double *P, const DgShape *B, double *dist, double *pts) {
    double p[3], n[3], low[3];
    const double *s = B->size;
    dg_origin(B->T, p);
    dg_column(P, 2, n);
    switch (B->kind) {
    case DG_SPHERE:
        dg_on_plane(P, p, 1, s[0], dist, pts);
        return;
    case DG_CAPSULE: {
        double u[3];
        dg_column(B->T, 2, u);
        double down = dg_dot(u, n) > 0 ? -1.0 : 1.0;
        double k = down * s[1];
        for (int i = 0; i < 3; ++i) low[i] = p[i] + k * u[i];
        dg_on_plane(P, low, 1, s[0], dist, pts);
        return;
    }
    case DG_BOX: {
        double ln[3], corner[3], wc[3];
        dg_to_local(B->T, n, ln);
        for (int i = 0; i < 3; ++i) corner[i] = (ln[i] > 0 ? -1.0 : 1.0) * s[i];
        dg_to_world(B->T, corner, wc);
        for (int i = 0; i < 3; ++i) low[i] = p[i] + wc[i];
        dg_on_plane(P, low, 0, 0.0, dist, pts);
        return;
    }
    case DG_CYLINDER: {
        double a[3], v[3], across[3];
        dg_column(B->T, 2, a);
        double na = dg_dot(n, a);
        double down = na > 0 ? -1.0 : 1.0;
        for (int i = 0; i < 3; ++i) v[i] = na * a[i] - n[i];
        dg_unit(v, DG_ZERO, across);
        double k = down * s[1];
        for (int i = 0; i < 3; ++i) low[i] = p[i] + k * a[i] + s[0] * across[i];
        dg_on_plane(P, low, 0, 0.0, dist, pts);
        return;
    }
    default: { /* DG_ELLIPSOID */
        double ln[3], m[3], mu[3], rm[3], w[3];
        dg_to_local(B->T, n, ln);
        for (int i = 0; i < 3; ++i) m[i] = ln[i] * s[i];
        dg_unit(m, DG_Z, mu);
        for (int i = 0; i < 3; ++i) rm[i] = s[i] * mu[i];
        dg_to_world(B->T, rm, w);
        for (int i = 0; i < 3; ++i) low[i] = p[i] - w[i];
        dg_on_plane(P, low, 0, 0.0, dist, pts);
        return;
    }
    }
}

/* gjk._plane_mesh: the plane against a mesh's lowest vertex */
static void dg_plane_mesh(const double *P, const DgShape *B, double *dist, double *pts) {
    double o[3], n[3], p[3];
    dg_origin(P, o);
    dg_column(P, 2, n);
    dg_origin(B->T, p);
    double best_h = 0.0, low[3] = {0.0, 0.0, 0.0};
    for (npy_intp k = 0; k < B->nverts; ++k) {
        double rv[3], world[3], rel[3];
        dg_to_world(B->T, B->verts + 3 * k, rv);
        for (int i = 0; i < 3; ++i) world[i] = p[i] + rv[i];
        dg_sub(world, o, rel);
        double h = dg_dot(rel, n);
        if (k == 0 || h < best_h) {
            best_h = h;
            memcpy(low, world, sizeof low);
        }
    }
    *dist = best_h;
    for (int i = 0; i < 3; ++i) {
        pts[i] = low[i] - best_h * n[i];
        pts[3 + i] = low[i];
    }
}

/* ------------------------------------------------------------------------------------------ */
/* support functions (gjk._Shape) */

/* the support point (world) of S's core in the world direction d */
static void dg_support(const DgShape *S, const double *d, double *out) {
    double l[3], s[3], rs[3], p[3];
    dg_to_local(S->T, d, l);
    const double *z = S->size;
    switch (S->kind) {
    case DG_SPHERE:
        s[0] = s[1] = s[2] = 0.0;
        break;
    case DG_CAPSULE:
        s[0] = s[1] = 0.0;
        s[2] = dg_sign(l[2]) * z[1];
        break;
    case DG_BOX:
        for (int i = 0; i < 3; ++i) s[i] = dg_sign(l[i]) * z[i];
        break;
    case DG_CYLINDER: {
        double rho = sqrt(l[0] * l[0] + l[1] * l[1]);
        double scale = rho > 0 ? z[0] / rho : 0.0;
        s[0] = l[0] * scale, s[1] = l[1] * scale, s[2] = dg_sign(l[2]) * z[1];
        break;
    }
    case DG_ELLIPSOID: {
        double m[3];
        for (int i = 0; i < 3; ++i) m[i] = z[i] * l[i];
        double length = sqrt(dg_dot(m, m));
        for (int i = 0; i < 3; ++i) s[i] = length > 0 ? z[i] * m[i] / length : 0.0;
        break;
    }
    default: { /* DG_MESH */
        npy_intp best = 0;
        double top = 0.0;
        for (npy_intp k = 0; k < S->nverts; ++k) {
            double h = dg_dot(l, S->verts + 3 * k);
            if (k == 0 || h > top) top = h, best = k;
        }
        memcpy(s, S->verts + 3 * best, sizeof s);
        break;
    }
    }
    dg_origin(S->T, p);
    dg_to_world(S->T, s, rs);
    for (int i = 0; i < 3; ++i) out[i] = p[i] + rs[i];
}

/* ------------------------------------------------------------------------------------------ */
/* GJK (gjk._run_gjk, _closest, _face_weights) */

/* every face of a simplex of 4 slots, in gjk._FACES' order */
static const int DG_FACES[15][5] = {
    {1, 0}, {1, 1}, {1, 2}, {1, 3}, {2, 0, 1}, {2, 0, 2}, {2, 0, 3}, {2, 1, 2},
    {2, 1, 3}, {2, 2, 3}, {3, 0, 1, 2}, {3, 0, 1, 3}, {3, 0, 2, 3}, {3, 1, 2, 3}, {4, 0, 1, 2, 3},
};

/* _face_weights: the barycentric weights of the point of the face's affine hull nearest the
 * origin; 0 where the face is degenerate */
static int dg_face_weights(double Y[4][3], const int *face, int k, double *lam) {
    const double *P0 = Y[face[0]];
    if (k == 1) {
        lam[0] = 1.0;
        return 1;
    }
    if (k == 2) {
        double e[3];
        dg_sub(Y[face[1]], P0, e);
        double ee = dg_dot(e, e);
        int ok = ee > 1e-28 * dg_max(dg_dot(P0, P0), 1e-300);
        double mu = -dg_dot(P0, e) / (ok ? ee : 1.0);
        lam[0] = 1 - mu, lam[1] = mu;
        return ok;
    }
    if (k == 3) {
        const double *P1 = Y[face[1]], *P2 = Y[face[2]];
        double e1[3], e2[3], n[3], c[3];
        dg_sub(P1, P0, e1);
        dg_sub(P2, P0, e2);
        dg_cross(e1, e2, n);
        double nn = dg_dot(n, n);
        double scale = dg_dot(e1, e1) * dg_dot(e2, e2);
        int ok = nn > 1e-24 * scale;
        double den = ok ? nn : 1.0;
        dg_cross(P1, P2, c);
        lam[0] = dg_dot(n, c) / den;
        dg_cross(P2, P0, c);
        lam[1] = dg_dot(n, c) / den;
        dg_cross(P0, P1, c);
        lam[2] = dg_dot(n, c) / den;
        return ok;
    }
    const double *a = P0, *b = Y[face[1]], *c = Y[face[2]], *d = Y[face[3]];
    double ba[3], ca[3], da[3], x[3];
    dg_sub(b, a, ba);
    dg_sub(c, a, ca);
    dg_sub(d, a, da);
    dg_cross(ca, da, x);
    double vol = dg_dot(ba, x);
    double edges = sqrt(dg_dot(ba, ba)) * sqrt(dg_dot(ca, ca));
    int ok = fabs(vol) > 1e-12 * edges * sqrt(dg_dot(da, da));
    double den = ok ? vol : 1.0;
    dg_cross(c, d, x);
    lam[0] = dg_dot(b, x) / den;
    lam[1] = -dg_dot(a, x) / den;
    dg_cross(b, d, x);
    lam[2] = dg_dot(a, x) / den;
    dg_cross(b, c, x);
    lam[3] = -dg_dot(a, x) / den;
    return ok;
}

/* _combine: sum_k w[k] Y[slots[k]] in the order of slots */
static inline void dg_combine(const double *w, double Y[][3], const int *slots, int k,
                              double *out) {
    for (int i = 0; i < 3; ++i) out[i] = w[0] * Y[slots[0]][i];
    for (int j = 1; j < k; ++j)
        for (int i = 0; i < 3; ++i) out[i] = out[i] + w[j] * Y[slots[j]][i];
}

static const int DG_SLOTS[4] = {0, 1, 2, 3};

/* _closest: the weights of the point of the simplex nearest the origin, the slots it uses */
static void dg_closest(double Y[4][3], const int *used, double *weights, int *members) {
    double best = INFINITY;
    for (int i = 0; i < 4; ++i) weights[i] = 0.0, members[i] = 0;
    for (int f = 0; f < 15; ++f) {
        int k = DG_FACES[f][0];
        const int *face = DG_FACES[f] + 1;
        int all_used = 1;
        for (int j = 0; j < k; ++j) all_used &= used[face[j]];
        if (!all_used) continue;
        double lam[4], x[3];
        int ok = dg_face_weights(Y, face, k, lam);
        for (int j = 0; j < k; ++j) ok &= lam[j] >= 0;
        if (!ok) continue;
        dg_combine(lam, Y, face, k, x);
        double norm2 = dg_dot(x, x);
        if (norm2 < best) {
            best = norm2;
            for (int i = 0; i < 4; ++i) weights[i] = 0.0, members[i] = 0;
            for (int j = 0; j < k; ++j) weights[face[j]] = lam[j], members[face[j]] = 1;
        }
    }
}

typedef struct {
    double Y[4][3], YA[4][3], YB[4][3];
    double pa[3], pb[3], dist;
    int inside;
} DgSimplex;

static void dg_gjk(const DgShape *A, const DgShape *B, const DgOptions *opt, DgSimplex *S) {
    int used[4] = {1, 0, 0, 0};
    double lam[4] = {1.0, 0.0, 0.0, 0.0}, d[3], nd[3], x[3];
    double pa[3], pb[3];
    memset(S, 0, sizeof *S);
    dg_origin(A->T, pa);
    dg_origin(B->T, pb);
    dg_sub(pa, pb, d);
    if (!(dg_dot(d, d) > 0)) d[0] = 1.0, d[1] = 0.0, d[2] = 0.0;
    for (int i = 0; i < 3; ++i) nd[i] = -d[i];
    dg_support(A, nd, S->YA[0]);
    dg_support(B, d, S->YB[0]);
    dg_sub(S->YA[0], S->YB[0], S->Y[0]);
    memcpy(x, S->Y[0], sizeof x);
    for (int it = 0; it < opt->max_iter; ++it) {
        double nx[3], sa[3], sb[3], w[3];
        for (int i = 0; i < 3; ++i) nx[i] = -x[i];
        dg_support(A, nx, sa);
        dg_support(B, x, sb);
        dg_sub(sa, sb, w);
        double xx = dg_dot(x, x);
        double norm = sqrt(xx);
        double gap = (xx - dg_dot(x, w)) / (norm > 0 ? norm : 1.0);
        if (gap <= opt->tol || norm <= opt->tol) break;
        int slot = 0;
        while (slot < 3 && used[slot]) ++slot; /* the first free slot (argmin of used) */
        memcpy(S->Y[slot], w, sizeof w);
        memcpy(S->YA[slot], sa, sizeof sa);
        memcpy(S->YB[slot], sb, sizeof sb);
        used[slot] = 1;
        double weights[4], x_new[3];
        int members[4];
        dg_closest(S->Y, used, weights, members);
        dg_combine(weights, S->Y, DG_SLOTS, 4, x_new);
        if (!(dg_dot(x_new, x_new) < dg_dot(x, x))) {
            used[slot] = 0; /* stalled: the simplex it had */
            break;
        }
        memcpy(x, x_new, sizeof x);
        memcpy(lam, weights, sizeof lam);
        memcpy(used, members, sizeof used);
        if (members[0] && members[1] && members[2] && members[3]) {
            S->inside = 1;
            break;
        }
    }
    dg_combine(lam, S->YA, DG_SLOTS, 4, S->pa);
    dg_combine(lam, S->YB, DG_SLOTS, 4, S->pb);
    double ab[3];
    dg_sub(S->pa, S->pb, ab);
    S->dist = sqrt(dg_dot(ab, ab));
}

/* ------------------------------------------------------------------------------------------ */
/* EPA (gjk._epa, _visit, _link) */

static int dg_reserve_faces(DgWork *W, int need) {
    if (need <= W->cap_faces) return 0;
    int cap = W->cap_faces > 0 ? W->cap_faces : 64;
    while (cap < need) cap *= 2;
    void *f = realloc(W->faces, (size_t)cap * sizeof *W->faces);
    if (f) W->faces = f;
    void *n = realloc(W->normals, (size_t)cap * sizeof *W->normals);
    if (n) W->normals = n;
    void *d = realloc(W->dists, (size_t)cap * sizeof *W->dists);
    if (d) W->dists = d;
    void *a = realloc(W->adj, (size_t)cap * sizeof *W->adj);
    if (a) W->adj = a;
    void *l = realloc(W->alive, (size_t)cap * sizeof *W->alive);
    if (l) W->alive = l;
    if (!f || !n || !d || !a || !l) return -1;
    W->cap_faces = cap;
    return 0;
}

static int dg_reserve_verts(DgWork *W, int need) {
    if (need <= W->cap_verts) return 0;
    int cap = W->cap_verts > 0 ? W->cap_verts : 64;
    while (cap < need) cap *= 2;
    void *v = realloc(W->verts, (size_t)cap * sizeof *W->verts);
    if (v) W->verts = v;
    void *a = realloc(W->va, (size_t)cap * sizeof *W->va);
    if (a) W->va = a;
    void *b = realloc(W->vb, (size_t)cap * sizeof *W->vb);
    if (b) W->vb = b;
    if (!v || !a || !b) return -1;
    W->cap_verts = cap;
    return 0;
}

static int dg_reserve_horizon(DgWork *W, int need) {
    if (need <= W->cap_horizon) return 0;
    int cap = W->cap_horizon > 0 ? W->cap_horizon : 64;
    while (cap < need) cap *= 2;
    void *h = realloc(W->horizon, (size_t)cap * sizeof *W->horizon);
    if (h) W->horizon = h;
    void *e = realloc(W->edges, (size_t)3 * cap * sizeof *W->edges);
    if (e) W->edges = e;
    if (!h || !e) return -1;
    W->cap_horizon = cap;
    return 0;
}

static void dg_free_work(DgWork *W) {
    free(W->verts), free(W->va), free(W->vb), free(W->faces), free(W->normals);
    free(W->dists), free(W->adj), free(W->alive), free(W->horizon), free(W->edges);
}

/* add: a face of the vertices f, its unit normal and its distance from the origin */
static void dg_add_face(DgWork *W, int f0, int f1, int f2) {
    int k = W->n_faces++;
    const double *p0 = W->verts[f0], *p1 = W->verts[f1], *p2 = W->verts[f2];
    double e1[3], e2[3], n[3];
    dg_sub(p1, p0, e1);
    dg_sub(p2, p0, e2);
    dg_cross(e1, e2, n);
    double length = sqrt(dg_dot(n, n));
    W->faces[k][0] = f0, W->faces[k][1] = f1, W->faces[k][2] = f2;
    for (int e = 0; e < 3; ++e) W->adj[k][e][0] = W->adj[k][e][1] = -1;
    W->alive[k] = 1;
    if (length <= 1e-300) { /* a degenerate face is never the nearest */
        memcpy(W->normals[k], n, sizeof n);
        W->dists[k] = INFINITY;
        return;
    }
    for (int i = 0; i < 3; ++i) W->normals[k][i] = n[i] / length;
    W->dists[k] = dg_dot(n, p0) / length;
}

/* _link: join the faces first..n_faces-1 across the edges they share, as the reference's
 * dictionary does (a repeated edge keeps its first place and its last face) */
static void dg_link(DgWork *W, int first) {
    int K = 0;
    for (int f = first; f < W->n_faces; ++f)
        for (int e = 0; e < 3; ++e) {
            int *E = W->edges[K++];
            E[0] = W->faces[f][e], E[1] = W->faces[f][(e + 1) % 3], E[2] = f, E[3] = e;
        }
    for (int i = 0; i < K; ++i) {
        int u = W->edges[i][0], v = W->edges[i][1], seen = 0, last = i, across = -1;
        for (int j = 0; j < i && !seen; ++j) seen = W->edges[j][0] == u && W->edges[j][1] == v;
        if (seen) continue;
        for (int j = 0; j < K; ++j) {
            if (W->edges[j][0] == u && W->edges[j][1] == v) last = j;
            if (W->edges[j][0] == v && W->edges[j][1] == u) across = j;
        }
        int f = W->edges[last][2], e = W->edges[last][3];
        if (W->adj[f][e][0] < 0 && across >= 0) {
            W->adj[f][e][0] = W->edges[across][2];
            W->adj[f][e][1] = W->edges[across][3];
        }
    }
}

/* _visit: the walk over the faces that w sees, entering face g by its edge e */
static int dg_visit(DgWork *W, int g, int e, const double *w) {
    if (g < 0 || !W->alive[g]) return 0;
    if (dg_dot(W->normals[g], w) - W->dists[g] <= 0) {
        if (dg_reserve_horizon(W, W->n_horizon + 1) < 0) return -1;
        W->horizon[W->n_horizon][0] = g, W->horizon[W->n_horizon][1] = e;
        W->n_horizon++;
        return 0;
    }
    W->alive[g] = 0;
    for (int step = 1; step <= 2; ++step) {
        int *a = W->adj[g][(e + step) % 3];
        if (dg_visit(W, a[0], a[1], w) < 0) return -1;
    }
    return 0;
}

/* EPA from GJK's tetrahedron S (which encloses the origin): the depth and the points of A and B
 * deepest in each other; -1 out of memory */
static int dg_epa(const DgShape *A, const DgShape *B, const DgOptions *opt, const DgSimplex *S,
                  DgWork *W, double *depth, double *pa, double *pb) {
    static const int TETRA[4][4] = {{0, 1, 2, 3}, {0, 3, 1, 2}, {0, 2, 3, 1}, {1, 3, 2, 0}};
    if (dg_reserve_verts(W, 4) < 0 || dg_reserve_faces(W, 4) < 0 || dg_reserve_horizon(W, 4) < 0)
        return -1;
    memcpy(W->verts, S->Y, sizeof S->Y);
    memcpy(W->va, S->YA, sizeof S->YA);
    memcpy(W->vb, S->YB, sizeof S->YB);
    W->n_verts = 4, W->n_faces = 0;
    for (int t = 0; t < 4; ++t) {
        const int *f = TETRA[t];
        const double *p0 = S->Y[f[0]], *p1 = S->Y[f[1]], *p2 = S->Y[f[2]], *other = S->Y[f[3]];
        double e1[3], e2[3], n[3], o[3];
        dg_sub(p1, p0, e1);
        dg_sub(p2, p0, e2);
        dg_cross(e1, e2, n);
        dg_sub(other, p0, o);
        if (dg_dot(n, o) < 0)
            dg_add_face(W, f[0], f[1], f[2]);
        else
            dg_add_face(W, f[0], f[2], f[1]);
    }
    dg_link(W, 0);
    double best = -INFINITY;
    int best_k = 0;
    for (;;) {
        int k = 0;
        double kd = W->alive[0] ? W->dists[0] : INFINITY;
        for (int j = 1; j < W->n_faces; ++j) {
            double dj = W->alive[j] ? W->dists[j] : INFINITY;
            if (dj < kd) kd = dj, k = j;
        }
        if (W->dists[k] < best) break;
        best = W->dists[k], best_k = k;
        const double *n = W->normals[k];
        double nn[3], sa[3], sb[3], w[3];
        for (int i = 0; i < 3; ++i) nn[i] = -n[i];
        dg_support(A, n, sa);
        dg_support(B, nn, sb);
        dg_sub(sa, sb, w);
        if (dg_dot(n, w) - W->dists[k] <= opt->epa_tol || W->n_faces >= opt->epa_faces) break;
        W->n_horizon = 0;
        W->alive[k] = 0;
        for (int e = 0; e < 3; ++e)
            if (dg_visit(W, W->adj[k][e][0], W->adj[k][e][1], w) < 0) return -1;
        if (dg_reserve_verts(W, W->n_verts + 1) < 0 ||
            dg_reserve_faces(W, W->n_faces + W->n_horizon) < 0 ||
            dg_reserve_horizon(W, W->n_horizon + 1) < 0)
            return -1;
        int new_vertex = W->n_verts++;
        memcpy(W->verts[new_vertex], w, sizeof w);
        memcpy(W->va[new_vertex], sa, sizeof sa);
        memcpy(W->vb[new_vertex], sb, sizeof sb);
        int first = W->n_faces;
        for (int h = 0; h < W->n_horizon; ++h) {
            int g = W->horizon[h][0], e = W->horizon[h][1];
            int u = W->faces[g][e], v = W->faces[g][(e + 1) % 3];
            dg_add_face(W, v, u, new_vertex);
            int last = W->n_faces - 1;
            W->adj[last][0][0] = g, W->adj[last][0][1] = e;
            W->adj[g][e][0] = last, W->adj[g][e][1] = 0;
        }
        dg_link(W, first);
    }
    /* the origin's projection on the nearest face, in barycentric coordinates */
    const double *n = W->normals[best_k];
    const int *f = W->faces[best_k];
    const double *P0 = W->verts[f[0]], *P1 = W->verts[f[1]], *P2 = W->verts[f[2]];
    double e1[3], e2[3], m[3], target[3], a[3], b[3], c[3], x[3], lam[3];
    dg_sub(P1, P0, e1);
    dg_sub(P2, P0, e2);
    dg_cross(e1, e2, m);
    for (int i = 0; i < 3; ++i) target[i] = best * n[i];
    dg_sub(P0, target, a);
    dg_sub(P1, target, b);
    dg_sub(P2, target, c);
    double mm = dg_dot(m, m);
    dg_cross(b, c, x);
    lam[0] = dg_dot(m, x) / mm;
    dg_cross(c, a, x);
    lam[1] = dg_dot(m, x) / mm;
    dg_cross(a, b, x);
    lam[2] = dg_dot(m, x) / mm;
    double PA[3][3], PB[3][3];
    for (int j = 0; j < 3; ++j) {
        memcpy(PA[j], W->va[f[j]], sizeof PA[j]);
        memcpy(PB[j], W->vb[f[j]], sizeof PB[j]);
    }
    dg_combine(lam, PA, DG_SLOTS, 3, pa);
    dg_combine(lam, PB, DG_SLOTS, 3, pb);
    *depth = best;
    return 0;
}

/* gjk.gjk for one pair of shapes without a plane; -1 out of memory */
static int dg_gjk_pair(const DgShape *A, const DgShape *B, const DgOptions *opt, DgWork *W,
                       double *dist, double *pts) {
    DgSimplex S;
    dg_gjk(A, B, opt, &S);
    double d = S.dist, pa[3], pb[3], sign = -1.0;
    memcpy(pa, S.pa, sizeof pa);
    memcpy(pb, S.pb, sizeof pb);
    if (S.inside && opt->depth) {
        if (dg_epa(A, B, opt, &S, W, &d, pa, pb) < 0) return -1;
        sign = 1.0;
    }
    double x[3], n12[3];
    dg_sub(pa, pb, x);
    double length = sqrt(dg_dot(x, x));
    for (int i = 0; i < 3; ++i) n12[i] = length > 0 ? sign * x[i] / length : 0.0;
    if (!opt->depth && S.inside) {
        d = 0.0;
        memcpy(pb, pa, sizeof pb);
    }
    *dist = (S.inside ? -d : d) - A->radius - B->radius;
    for (int i = 0; i < 3; ++i) {
        pts[i] = pa[i] + A->radius * n12[i];
        pts[3 + i] = pb[i] - B->radius * n12[i];
    }
    return 0;
}

/* gjk.distance for one pair: a closed form where there is one (either order), else GJK and
 * EPA (gjk.gjk: opt->closed 0); the points in the order given. -1 out of memory. Two planes
 * never reach here. */
static int dg_distance(const DgShape *A, const DgShape *B, const DgOptions *opt, DgWork *W,
                       double *dist, double *pts) {
    int ka = A->kind, kb = B->kind;
    int flip = kb == DG_PLANE || (opt->closed && kb == DG_SPHERE && (ka == DG_CAPSULE ||
                                                                      ka == DG_BOX ||
                                                                      ka == DG_CYLINDER));
    if (flip) {
        double q[6];
        int rc = dg_distance(B, A, opt, W, dist, q);
        memcpy(pts, q + 3, 3 * sizeof *q);
        memcpy(pts + 3, q, 3 * sizeof *q);
        return rc;
    }
    if (ka == DG_PLANE) {
        if (kb == DG_MESH)
            dg_plane_mesh(A->T, B, dist, pts);
        else
            dg_plane_shape(A->T, B, dist, pts);
        return 0;
    }
    if (!opt->closed) return dg_gjk_pair(A, B, opt, W, dist, pts);
    if (ka == DG_SPHERE) {
        switch (kb) {
        case DG_SPHERE: dg_sphere_sphere(A, B, dist, pts); return 0;
        case DG_CAPSULE: dg_sphere_capsule(A, B, dist, pts); return 0;
        case DG_BOX: dg_sphere_box(A, B, dist, pts); return 0;
        case DG_CYLINDER: dg_sphere_cylinder(A, B, dist, pts); return 0;
        default: break;
        }
    }
    if (ka == DG_CAPSULE && kb == DG_CAPSULE) {
        dg_capsule_capsule(A, B, dist, pts);
        return 0;
    }
    return dg_gjk_pair(A, B, opt, W, dist, pts);
}

static inline void dg_shape(DgShape *S, int kind, const double *T, const double *size,
                            const double *verts, npy_intp nverts) {
    S->kind = kind, S->T = T, S->size = size, S->verts = verts, S->nverts = nverts;
    S->radius = (kind == DG_SPHERE || kind == DG_CAPSULE) ? size[0] : 0.0;
}
