/*
 * The inverse kinematics solvers' parts that do not depend on the vector width: the numerical
 * solver's model and options, its random numbers, and scalar helpers (ik_wrap serves the analytic
 * solver too). Included by _kernel.c before the
 * per-width kernels (_ik_core.h); the algorithm is described in poekin/ik/numerical.py, whose
 * NumPy reference this code repeats operation for operation.
 */

#define IK_STEP_MAX_JOINTS 16 /* the differential step (_ik_step.h); more: the NumPy reference */
#define IK_STEP_FLOOR 1e-18  /* poekin.ik.step.FLOOR */
#define IK_MAX_JOINTS 4096 /* the random starts' counter has 16 bits for the joint */
#define IK_PI 3.141592653589793116     /* numpy.pi */
#define IK_TWO_PI 6.283185307179586232 /* 2 * numpy.pi */
/* joint flags */
#define IK_REVOLUTE 1
#define IK_CYCLIC 2 /* revolute without limits: kept in (-pi, pi] */
/* Below this many targets per thread, another thread does not pay for its start. */
#define IK_MIN_TARGETS_PER_THREAD 32

/* The chain: its world-Jacobian program and, per joint, limits, flags and random starts
 * base + u span (poekin._poe.ChainTerms). */
typedef struct {
    const Program *prog;
    int n;
    const double *lo, *hi, *base, *span;
    const int *flags;
} IKModel;

/* poekin.ik.numerical._kernel_options, in its order. */
typedef struct {
    double pos_tol, ori_tol, pos_tol2, ori_tol2, weight, damping, floor, ceiling, step_max,
        stall_factor;
    int stall_iterations, position_only, max_iterations, max_attempts;
} IKOptions;
#define IK_N_OPTIONS 14

typedef struct {
    const IKModel *model;
    const IKOptions *opt;
    uint64_t seed;
    const double *T;  /* (N, 4, 4) */
    const double *q0; /* (N, n), or NULL */
    npy_intp N;
    npy_intp *next; /* the next target to start, shared by the threads */
    int group;      /* lanes per target (a power of two, dividing the width): see _ik_core.h */
    double *q;      /* (N, n) */
    npy_bool *success;
    double *pos_err, *ori_err;
    int64_t *iterations, *attempts;
    int bad; /* -1: out of memory */
} IKTask;

/* poekin.ik.numerical.FAR: a target position beyond this along any axis (m) is aimed at from
 * this distance */
#define IK_FAR 1e6

/* The position the solve aims at for target T (poekin.ik.numerical.aimed): T's own, or, beyond
 * IK_FAR along any axis, the point at that distance on the line from the origin to it. */
static inline void ik_aimed(const double *T, double p[3]) {
    const double m = fmax(fmax(fabs(T[3]), fabs(T[7])), fabs(T[11]));
    if (!(m > IK_FAR)) {
        for (int i = 0; i < 3; ++i) p[i] = T[4 * i + 3];
        return;
    }
    double u[3];
    for (int i = 0; i < 3; ++i) u[i] = T[4 * i + 3] / m;
    const double factor = IK_FAR / sqrt((u[0] * u[0] + u[1] * u[1]) + u[2] * u[2]);
    for (int i = 0; i < 3; ++i) p[i] = u[i] * factor;
}

/* |e| (poekin.ik.numerical.distance): where an entry exceeds 1e150 (HUGE), m |e / m| for
 * m = max |e_i|, whose squares cannot overflow. */
static inline double ik_distance(const double e[3]) {
    const double m = fmax(fmax(fabs(e[0]), fabs(e[1])), fabs(e[2]));
    const double scale = m > 1e150 ? m : 1.0;
    const double u[3] = {e[0] / scale, e[1] / scale, e[2] / scale};
    const double sq = (u[0] * u[0] + u[1] * u[1]) + u[2] * u[2];
    return scale * (sq > 0 ? sqrt(sq) : 0.0);
}

/* SplitMix64's output for state x (poekin.ik._rng.mix). */
static inline uint64_t ik_mix(uint64_t x) {
    uint64_t z = x + 0x9E3779B97F4A7C15ULL;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
}

static inline uint64_t ik_bits(double x) {
    uint64_t u;
    memcpy(&u, &x, sizeof u);
    return u;
}

/* A target's key: the seed, then the bits of T's top three rows, then of q0 (poekin.ik._rng.
 * target_keys). */
static uint64_t ik_key(uint64_t seed, const double *T, const double *q0, int n) {
    uint64_t key = ik_mix(seed);
    for (int j = 0; j < 12; ++j) key = ik_mix(key ^ ik_bits(T[j]));
    if (q0 != NULL)
        for (int j = 0; j < n; ++j) key = ik_mix(key ^ ik_bits(q0[j]));
    return key;
}

/* Joint j's random start at attempt a (poekin.ik.numerical.starts). */
static inline double ik_start(const IKModel *m, uint64_t key, int64_t a, int j) {
    uint64_t counter = ((uint64_t)a << 16) | (uint64_t)j;
    double u = (double)(ik_mix(key ^ ik_mix(counter)) >> 11) * 0x1p-53;
    return m->base[j] + u * m->span[j];
}

/* numpy.mod of doubles: fmod, moved to the divisor's sign (npy_divmod). */
static inline double ik_np_mod(double a, double b) {
    double mod = fmod(a, b);
    if (mod != 0.0) {
        if ((b < 0) != (mod < 0)) mod += b;
    } else {
        mod = copysign(0.0, b);
    }
    return mod;
}

/* x moved by whole turns into [lo, hi] where that helps, a cyclic joint's into (-pi, pi]; a
 * value already there is returned as it is (poekin.ik.numerical.wrapped, which calls
 * poekin.ik._angles.wrap_into_limits: the same arithmetic). */
static inline double ik_wrap(double x, double lo, double hi, int flags) {
    if (!(flags & IK_REVOLUTE)) return x;
    if (flags & IK_CYCLIC) {
        if (x > -IK_PI && x <= IK_PI) return x;
        return IK_PI - ik_np_mod(IK_PI - x, IK_TWO_PI);
    }
    if (x >= lo && x <= hi) return x;
    if (x < lo) {
        double raised = x + ceil((lo - x) / IK_TWO_PI) * IK_TWO_PI;
        return raised <= hi ? raised : x;
    }
    double lowered = x + floor((hi - x) / IK_TWO_PI) * IK_TWO_PI;
    return lowered >= lo ? lowered : x;
}

/* The flags of a revolute joint with limits [lo, hi] (IK_CYCLIC without either). */
static inline int ik_revolute_flags(double lo, double hi) {
    return IK_REVOLUTE | (isinf(lo) && lo < 0 && isinf(hi) && hi > 0 ? IK_CYCLIC : 0);
}

/* numpy.maximum and numpy.minimum: the first argument where the comparison holds. */
static inline double ik_clamp(double x, double lo, double hi) {
    double a = x >= lo ? x : lo;
    return a <= hi ? a : hi;
}
