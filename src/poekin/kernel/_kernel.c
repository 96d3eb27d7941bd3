/*
 * poekin.kernel._kernel: the compiled forward-kinematics kernel.
 *
 * One generic interpreter serves every FK path (space PoE, body PoE, whole trees). Python
 * compiles a model into a small *program* of pose operations (see poekin/kernel/_fast.py); this file
 * runs it on blocks of LANES configurations at once, each operation one SIMD instruction
 * sequence over the block (GCC vector types), and on several threads for big batches. The code
 * that depends on LANES is in _kernel_core.h, compiled three times: 8 lanes for AVX-512, 4 for
 * AVX2, 2 for everything else (SSE2, NEON); the widest the CPU runs is picked at import.
 *
 * The state is one rigid transform per lane, ``cur = (R, t)``. Operations right-multiply it,
 * in the same order and with the same formulas as the pure-NumPy reference path
 * (poekin.chain.poe and poekin._levels.evaluate), so that both agree to ~1e-16.
 *
 * Floating point: built with -ffp-contract=off and without -ffast-math, so the result of one
 * configuration is the same bits whatever the batch size, the lane, the thread count or the
 * instruction set chosen at run time.
 *
 * sin and cos: a branch-free Cody-Waite reduction to a double-double remainder and fdlibm's
 * minimax kernels (error below 1 ulp), vectorised over lanes; arguments beyond 2^19 rad go to
 * the C library's sin and cos.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#include <numpy/arrayobject.h>

#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#ifdef _WIN32
#include <windows.h>
#else
#include <pthread.h>
#endif


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
    /* rotation about coordinate axis x, y or z through a point, then (_PITCH) along it; params:
     * scale, offset, ref, sign, point[(k+1)%3], point[(k+2)%3], pitch (k = 0, 1, 2 for x, y, z) */
    OP_AXIS_X = 10,
    OP_AXIS_Y = 11,
    OP_AXIS_Z = 12,
    OP_AXIS_X_PITCH = 13,
    OP_AXIS_Y_PITCH = 14,
    OP_AXIS_Z_PITCH = 15,
    OP_TRANSLATE = 16, /* cur = cur * (I, t); params: t (3) */
    OP_JCOL = 17,      /* Jacobian column a3 += scale Ad(cur) [w; v]; params: w, v, scale */
    OP_JEMIT = 18,     /* write the columns in a convention at the end pose; params: JAC_*, n */
};
#define N_OPS 19
enum { JAC_SPACE = 0, JAC_BODY = 1, JAC_WORLD = 2 };
/* SCREW, HINGE and the AXIS operations turn by an angle; each names its angle's index in slot */
#define HAS_ANGLE(code) \
    ((code) == OP_SCREW || (code) == OP_HINGE || ((code) >= OP_AXIS_X && (code) <= OP_AXIS_Z_PITCH))

enum { FORM_4X4 = 0, FORM_3X4 = 1, FORM_POS_QUAT = 2 };
static const int FORM_SIZE[3] = {16, 12, 7};

/* Work per thread, in operations times configurations, below which another thread does not
 * pay for its start: 8,192 UR5e configurations (9 operations each), 1,602 of a go2 (46). */
#define MIN_WORK_PER_THREAD 73728
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

/* Inlined helpers of the kernel, compiled for the instruction set of the kernel that uses them
 * (TARGET, set before each inclusion of _kernel_core.h). */
#define AI static inline __attribute__((always_inline)) TARGET


/* ------------------------------------------------------------------------------------------ */
/* the interpreter */

/* An angle is q[qadr] (plain: a SCREW, or scale 1, offset 0, ref 0) or (q[qadr] scale + offset)
 * - ref with P = (scale, offset, ref). */
typedef struct {
    const double *P;
    int32_t qadr;
    int32_t plain;
} AngleSource;

/* One operation, decoded: its code, qpos address, slot (or angle index) and parameters. */
typedef struct {
    int32_t code, a, slot;
    const double *P;
} Op;

typedef struct {
    const Op *ops; /* decoded; their parameters point into the params array */
    int n_ops;
    int nq;
    int n_slots;
    int n_out;
    int n_angles;  /* operations that turn by an angle (HAS_ANGLE), rounded up to even */
    const AngleSource *angles; /* where each angle comes from (an odd count's last twice) */
    int jac_cols;  /* JEMIT's column count: a Jacobian program's output is (6, jac_cols) */
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

/* Numbers per output frame: the form's, or a Jacobian's 6 x columns. */
static int out_size(const Program *prog, int form) {
    return prog->jac_cols > 0 ? 6 * prog->jac_cols : FORM_SIZE[form];
}

/* Scratch that fits in this many bytes lives on the stack (no malloc per call). */
#define STACK_SCRATCH 32768

static unsigned char *aligned_malloc(size_t bytes) {
    size_t rounded = (bytes + 64 - 1) / 64 * 64;
#ifdef _WIN32
    return _aligned_malloc(rounded, 64);
#else
    return aligned_alloc(64, rounded);
#endif
}

static void aligned_free(unsigned char *p) {
#ifdef _WIN32
    _aligned_free(p);
#else
    free(p);
#endif
}


#include "_ik_common.h" /* both IK solvers' scalar helpers (ik_wrap) */

/* ------------------------------------------------------------------------------------------ */
/* analytic IK (poekin.ik.analytic): the constants of each closed-form split, as the reference
 * writes them (analytic._flat: its dataclasses' fields in order, all doubles) */

enum { IK_THREE_PARALLEL = 0, IK_TWO_PARALLEL = 1, IK_ONE_TWO_MEET = 2, IK_TWO_THREE_MEET = 3 };

typedef struct { /* analytic._Wrist */
    double h[6][3], minus[6][3], h6_end[3], x6[3], x6_end[3], d56, tol, tiny;
} IkWrist;

typedef struct { /* analytic._ThreeParallel */
    IkWrist w;
    double h[3], minus_h[3], h3[3], sign3, sign4, r1[3], r2[3], c56_end[3], d1, c56_r4[3],
        p32[3], p43[3], p23[3], tol, tiny, tol2, tiny2;
} IkThreeParallel;

typedef struct { /* analytic._TwoParallel */
    double h2[3], h3[3], minus_h1[3], r1[3], r2[3], pw3[3], p23[3], p32[3], d1, tol, tiny, tol2,
        tiny2;
} IkTwoParallel;

typedef struct { /* analytic._OneTwoMeet */
    double h2[3], h3[3], minus_h1[3], c[3], pw3[3], pc3[3], p3c[3], tol, tiny, tol2, tiny2;
} IkOneTwoMeet;

typedef struct { /* analytic._TwoThreeMeet */
    double h3[3], minus_h1[3], minus_h2[3], r1[3], pc1[3], pwc[3], c[3], dist2, d3, tol, tiny,
        tol2, tiny2;
} IkTwoThreeMeet;

typedef struct { /* analytic._Spherical */
    IkWrist w;
    double pw_end[3];
    union {
        IkTwoParallel two_parallel;
        IkOneTwoMeet one_two_meet;
        IkTwoThreeMeet two_three_meet;
    } s;
} IkSpherical;

/* The branch index bits (4 i1 + 2 i2 + i3) each joint's angle does not depend on, by kind:
 * three parallel axes, q1 on i1 only, q5 and q6 not on the elbow i3; spherical wrist, q1 to q3
 * not on the wrist's i3. */
static const int IK_SHARED[4][6] = {
    {3, 0, 0, 0, 1, 1}, {1, 1, 1, 0, 0, 0}, {1, 1, 1, 0, 0, 0}, {1, 1, 1, 0, 0, 0}};

/* The number of doubles of each split's constants. */
static npy_intp ik_params_size(int kind) {
    const npy_intp head = (npy_intp)offsetof(IkSpherical, s);
    switch (kind) {
        case IK_THREE_PARALLEL: return sizeof(IkThreeParallel) / sizeof(double);
        case IK_TWO_PARALLEL: return (head + sizeof(IkTwoParallel)) / sizeof(double);
        case IK_ONE_TWO_MEET: return (head + sizeof(IkOneTwoMeet)) / sizeof(double);
        case IK_TWO_THREE_MEET: return (head + sizeof(IkTwoThreeMeet)) / sizeof(double);
        default: return -1;
    }
}

typedef struct {
    int kind;
    const void *params; /* the split's struct, read from the constants array */
    const double *T;    /* (n, 16) targets */
    const double *limits; /* (6, 2) */
    double *q;          /* (n, 8, 6) */
    uint8_t *valid;     /* (n, 8) */
    npy_intp lo, hi;
} IkAllTask;

/* Whether target T (16 numbers) is not a rigid transform as poekin.ik.analytic._targets
 * decides: NaN or inf, R^T R off the identity by more than 1e-6, det R < 0, or a last row
 * other than [0, 0, 0, 1]. */
static int ik_bad_target(const double *T) {
    for (int e = 0; e < 16; ++e)
        if (!isfinite(T[e])) return 1;
    if (T[12] != 0.0 || T[13] != 0.0 || T[14] != 0.0 || T[15] != 1.0) return 1;
    for (int i = 0; i < 3; ++i)
        for (int k = 0; k < 3; ++k) {
            double g = T[i] * T[k] + T[4 + i] * T[4 + k] + T[8 + i] * T[8 + k];
            if (fabs(g - (i == k ? 1.0 : 0.0)) > 1e-6) return 1;
        }
    double det = T[0] * (T[5] * T[10] - T[6] * T[9]) - T[1] * (T[4] * T[10] - T[6] * T[8]) +
                 T[2] * (T[4] * T[9] - T[5] * T[8]);
    return det < 0.0;
}

/* ------------------------------------------------------------------------------------------ */
/* one kernel per vector width, each compiled for the instruction set that has it */

#if (defined(__x86_64__) || defined(_M_X64)) && defined(__GNUC__)
#define X86_DISPATCH 1
#endif

#define LANES 2 /* SSE2 on x86-64, NEON on arm64: every CPU these run on */
#define TARGET
#include "_kernel_core.h"
#include "_ik_all.h"
#undef LANES
#undef TARGET

#ifdef X86_DISPATCH
#define LANES 4
#define TARGET __attribute__((target("avx2,fma")))
#include "_kernel_core.h"
#include "_ik_all.h"
#undef LANES
#undef TARGET

#define LANES 8
#define TARGET __attribute__((target("avx512f,avx512dq,avx512vl,avx512bw,avx2,fma")))
#include "_kernel_core.h"
#include "_ik_all.h"
#undef LANES
#undef TARGET
#endif

typedef void (*TaskFn)(Task *);
static TaskFn g_run_task = run_task_2;
typedef void (*IkAllTaskFn)(IkAllTask *);
static IkAllTaskFn g_ik_all_task = ik_all_task_2;
typedef void (*IKTaskFn)(IKTask *);
static IKTaskFn g_ik_run_task = ik_run_task_2;
typedef int (*IKStepFn)(const IKModel *, const IKOptions *, const double *, const double *,
                        const double *, double, double, double, int, npy_intp, npy_intp,
                        double *);
static IKStepFn g_ik_step_task = ik_step_task_2;
static int g_lanes = 2;

/* The widest kernel this CPU runs; widest = 0 picks the best, else 2, 4 or 8. -1: not here. */
static int choose_width(int widest) {
    int best = 2;
#ifdef X86_DISPATCH
    __builtin_cpu_init();
    if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) best = 4;
    if (best == 4 && __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512dq") &&
        __builtin_cpu_supports("avx512vl") && __builtin_cpu_supports("avx512bw"))
        best = 8;
#endif
    int w = widest == 0 ? best : widest;
    if (w != 2 && w != 4 && w != 8) return -1;
    if (w > best) return -1;
    g_lanes = w;
#ifdef X86_DISPATCH
    g_run_task = w == 8 ? run_task_8 : w == 4 ? run_task_4 : run_task_2;
    g_ik_all_task = w == 8 ? ik_all_task_8 : w == 4 ? ik_all_task_4 : ik_all_task_2;
    g_ik_run_task = w == 8 ? ik_run_task_8 : w == 4 ? ik_run_task_4 : ik_run_task_2;
    g_ik_step_task = w == 8 ? ik_step_task_8 : w == 4 ? ik_step_task_4 : ik_step_task_2;
#endif
    return w;
}

/* One share of a batch: fn(arg), on a thread of its own or on the caller's. */
typedef struct {
    void (*fn)(void *);
    void *arg;
} Share;

#ifdef _WIN32
static DWORD WINAPI share_main(LPVOID share) {
    ((Share *)share)->fn(((Share *)share)->arg);
    return 0;
}
#else
static void *share_main(void *share) {
    ((Share *)share)->fn(((Share *)share)->arg);
    return NULL;
}
#endif

/* Run the nt shares: the first here, the others on threads of their own (or here, where no
 * thread is to be had), and wait for them all. */
static void run_shares(Share *shares, int nt) {
#ifdef _WIN32
    HANDLE handles[MAX_THREADS];
#else
    pthread_t handles[MAX_THREADS];
#endif
    int started[MAX_THREADS];
    for (int k = 1; k < nt; ++k) {
#ifdef _WIN32
        handles[k] = CreateThread(NULL, 0, share_main, &shares[k], 0, NULL);
        started[k] = handles[k] != NULL;
#else
        started[k] = pthread_create(&handles[k], NULL, share_main, &shares[k]) == 0;
#endif
    }
    shares[0].fn(shares[0].arg);
    for (int k = 1; k < nt; ++k) {
        if (started[k]) {
#ifdef _WIN32
            WaitForSingleObject(handles[k], INFINITE);
            CloseHandle(handles[k]);
#else
            pthread_join(handles[k], NULL);
#endif
        } else {
            shares[k].fn(shares[k].arg);
        }
    }
}

/* How many threads share n items, at least per_thread each, and the items per thread (whole
 * blocks of every width). */
static int split_batch(npy_intp n, npy_intp per_thread, int threads, npy_intp *chunk) {
    npy_intp most = n / (per_thread > 0 ? per_thread : 1);
    int nt = threads < most ? threads : (int)(most > 0 ? most : 1);
    if (nt > MAX_THREADS) nt = MAX_THREADS;
    npy_intp c = (n + nt - 1) / nt;
    *chunk = (c + 7) / 8 * 8;
    return nt;
}

static void fk_share(void *task) { g_run_task((Task *)task); }

/* Run prog on n configurations on up to g_threads threads. 0: done, 1: a q is not finite,
 * -1: out of memory. */
static int run_program(const Program *prog, const double *q, npy_intp n, double *out, int form,
                       int threads) {
    Task tasks[MAX_THREADS];
    Share shares[MAX_THREADS];
    npy_intp chunk;
    int nt = split_batch(n, MIN_WORK_PER_THREAD / (prog->n_ops > 0 ? prog->n_ops : 1), threads,
                         &chunk);
    for (int k = 0; k < nt; ++k) {
        npy_intp lo = k * chunk < n ? k * chunk : n;
        npy_intp hi = lo + chunk < n ? lo + chunk : n;
        tasks[k] = (Task){prog, q, out, lo, hi, form, 0};
        shares[k] = (Share){fk_share, &tasks[k]};
    }
    run_shares(shares, nt);
    int status = 0;
    for (int k = 0; k < nt; ++k)
        if (tasks[k].bad && !status) status = tasks[k].bad;
    return status;
}

/* ------------------------------------------------------------------------------------------ */
/* Python type: Kernel(ops, params, nq, n_slots, n_out, frame_axis) */

typedef struct {
    PyObject_HEAD Program prog;
    PyObject *ops_obj;    /* keeps the int32 ops array alive */
    PyObject *params_obj; /* keeps the float64 params array alive */
    AngleSource *angles;  /* owned: Program.angles */
    Op *ops;              /* owned: Program.ops */
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
    PyMem_Free(self->angles);
    PyMem_Free(self->ops);
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
    int n_angles = 0, jac_cols = 0;
    npy_intp bad = -1; /* the first operation out of range */
    static const int QSIZE[N_OPS] = {0, 0, 0, 0, 1, 1, 1, 4, 7, 0, 1, 1, 1, 1, 1, 1, 0, 0, 0};
    static const int PSIZE[N_OPS] = {0, 0, 0, 12, 24, 24, 6, 3, 0, 0, 7, 7, 7, 7, 7, 7, 3, 7, 2};
    const double *pd = PyArray_DATA(p);
    for (npy_intp k = 0; k < n_ops; ++k) {
        const int32_t *op = code + 4 * k;
        int ok = op[0] >= 0 && op[0] < N_OPS && op[1] >= 0 && op[1] + QSIZE[op[0]] <= nq &&
                 op[2] >= 0 && op[2] + PSIZE[op[0]] <= n_params;
        if (ok && (op[0] == OP_LOAD || op[0] == OP_STORE)) ok = op[3] >= 0 && op[3] < n_slots;
        if (ok && op[0] == OP_EMIT) ok = op[3] >= 0 && op[3] < n_out;
        if (ok && HAS_ANGLE(op[0])) ok = op[3] == n_angles++;
        if (ok && op[0] == OP_JEMIT) { /* one column count for the whole program */
            double c = pd[op[2]], cols = pd[op[2] + 1];
            ok = (c == JAC_SPACE || c == JAC_BODY || c == JAC_WORLD) && cols >= 1 &&
                 cols <= 65536 && cols == (int)cols && (jac_cols == 0 || jac_cols == (int)cols);
            jac_cols = (int)cols;
        }
        if (!ok) {
            bad = k;
            break;
        }
    }
    for (npy_intp k = 0; k < n_ops && bad < 0; ++k) { /* a column is one the program writes */
        const int32_t *op = code + 4 * k;
        if (op[0] == OP_JCOL && !(op[3] >= 0 && op[3] < jac_cols)) bad = k;
    }
    if (bad >= 0) {
        Py_DECREF(o);
        Py_DECREF(p);
        PyErr_Format(PyExc_ValueError, "operation %zd is out of range", (Py_ssize_t)bad);
        return -1;
    }
    /* an even count, the last repeated: the kernel takes the angles two at a time */
    const int n_paired = (n_angles + 1) / 2 * 2;
    AngleSource *angles = PyMem_Malloc(sizeof(AngleSource) * (n_paired > 0 ? n_paired : 1));
    Op *decoded = PyMem_Malloc(sizeof(Op) * (n_ops > 0 ? n_ops : 1));
    if (angles == NULL || decoded == NULL) {
        PyMem_Free(angles);
        PyMem_Free(decoded);
        Py_DECREF(o);
        Py_DECREF(p);
        PyErr_NoMemory();
        return -1;
    }
    for (npy_intp k = 0; k < n_ops; ++k) {
        const int32_t *op = code + 4 * k;
        const double *P = pd + op[2];
        decoded[k] = (Op){op[0], op[1], op[3], P};
        if (!HAS_ANGLE(op[0])) continue;
        int plain = op[0] == OP_SCREW || (P[0] == 1.0 && P[1] == 0.0 && P[2] == 0.0);
        angles[op[3]] = (AngleSource){P, op[1], plain};
    }
    if (n_paired > n_angles) angles[n_angles] = angles[n_angles - 1];
    PyMem_Free(self->angles);
    PyMem_Free(self->ops);
    self->angles = angles;
    self->ops = decoded;
    Py_XSETREF(self->ops_obj, (PyObject *)o);
    Py_XSETREF(self->params_obj, (PyObject *)p);
    /* the angles are q (screws) or (q scale + offset) - ref (hinges, axes): bound them */
    double gain = 1.0, shift = 0.0;
    for (npy_intp k = 0; k < n_ops; ++k) {
        if (code[4 * k] == OP_SCREW || !HAS_ANGLE(code[4 * k])) continue;
        const double *P = pd + code[4 * k + 2];
        if (fabs(P[0]) > gain) gain = fabs(P[0]);
        if (fabs(P[1]) + fabs(P[2]) > shift) shift = fabs(P[1]) + fabs(P[2]);
    }
    double huge_q = (REDUCE_MAX - shift) / gain;
    self->prog = (Program){decoded,  (int)n_ops, nq, n_slots, n_out, n_paired, angles, jac_cols,
                           huge_q > 0 ? huge_q : 0.0};
    self->frame_axis = frame_axis;
    return 0;
}

/* The forms' names, interned: the callers' literals are the same objects. */
static PyObject *g_form_names[3];

/* FORM_* of a form's name, or -1. */
static int form_code(PyObject *form) {
    for (int k = 0; k < 3; ++k)
        if (form == g_form_names[k]) return k;
    if (!PyUnicode_Check(form)) return -1;
    for (int k = 0; k < 3; ++k)
        if (PyUnicode_Compare(form, g_form_names[k]) == 0) return k;
    PyErr_Clear();
    return -1;
}

/* run(q, out=None, form="4x4"): the poses of q, or None if it cannot take the arguments as they
 * are: q not a C-contiguous float64 array of shape (..., nq) with finite values, out not a
 * writeable C-contiguous float64 array of the result's shape, an unknown form. The caller then
 * validates and converts, or says what is wrong. */
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
    int form = nargs == 3 ? form_code(args[2]) : FORM_4X4;
    if (form < 0) Py_RETURN_NONE;
    npy_intp dims[NPY_MAXDIMS];
    int out_nd = 0;
    npy_intp n = 1;
    for (int i = 0; i < nd - 1; ++i) {
        dims[out_nd++] = PyArray_DIM(q, i);
        n *= PyArray_DIM(q, i);
    }
    if (out_nd + 3 > NPY_MAXDIMS) Py_RETURN_NONE;
    if (self->frame_axis) dims[out_nd++] = prog->n_out;
    if (prog->jac_cols > 0) {
        if (form != FORM_4X4) Py_RETURN_NONE; /* a Jacobian has no other form */
        dims[out_nd++] = 6;
        dims[out_nd++] = prog->jac_cols;
    } else if (form == FORM_POS_QUAT) {
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
            !PyArray_CompareLists(PyArray_DIMS(out), dims, out_nd))
            Py_RETURN_NONE;
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
     "run(q, out=None, form='4x4') -> poses, or None if the arguments need validating first"},
    {"__reduce__", (PyCFunction)Kernel_reduce, METH_NOARGS, NULL},
    {NULL, NULL, 0, NULL},
};

static PyTypeObject KernelType = {
    PyVarObject_HEAD_INIT(NULL, 0).tp_name = "poekin.kernel._kernel.Kernel",
    .tp_basicsize = sizeof(KernelObject),
    .tp_dealloc = (destructor)Kernel_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "A compiled forward-kinematics program (built by poekin.kernel._fast).",
    .tp_methods = Kernel_methods,
    .tp_init = (initproc)Kernel_init,
    .tp_new = PyType_GenericNew,
};

/* ------------------------------------------------------------------------------------------ */
/* Python type: IKSolver, a chain's inverse kinematics */

#include "_ik_type.h"

/* ------------------------------------------------------------------------------------------ */
/* Python type: FastMethod(kernel_attr, fallback, names), a method that runs the kernel first */

/* A method whose call `obj.m(q, out, form)` (or `obj.m(q)`) first runs `getattr(obj,
 * kernel_attr).run(q, out, form)` in C, and calls the Python function `fallback(obj, ...)` with
 * the arguments as given only when there is no kernel or it answers None (arguments that need
 * validating or converting, other array libraries, or errors to report). names: the fallback's
 * parameter names after self that the kernel takes, for keywords: (q, out, form) or (q,); any
 * other keyword goes to the fallback. It saves a Python frame per call: a controller's single
 * calls are as fast as the kernel's own.
 *
 * The attribute may instead hold a tuple (fn, *bound), which the Python side sets once it
 * knows what the call with the other arguments at their defaults needs (Chain.ik's solver and
 * options): the call is then fn(obj, the named parameters with None for those not given,
 * *bound), and the fallback runs where fn answers None.
 *
 * Tools that trace Python rather than run it (torch.compile's Dynamo) cannot enter this C call:
 * for them the type's dict holds a __get__ and a __call__ written in Python (expose_python) that
 * bind and call the Python fallback instead, which they trace. The interpreter never uses that entry (it calls the C
 * slots), so calls keep their speed, and a non-data method descriptor keeps CPython's
 * specialised method call. */
#define FAST_MAX_BOUND 8 /* the most bound arguments of a (fn, *bound) */

typedef struct {
    PyObject_HEAD PyObject *attr; /* interned name of the instance attribute holding the Kernel */
    PyObject *fallback;
    PyObject *names; /* tuple of 1 to 3 interned parameter names: q, out, form */
    PyObject *dict;  /* __doc__, __wrapped__, ... (functools.update_wrapper) */
    vectorcallfunc vectorcall;
} FastMethodObject;

static PyObject *FastMethod_vectorcall(FastMethodObject *self, PyObject *const *args,
                                       size_t nargsf, PyObject *kwnames) {
    Py_ssize_t nargs = PyVectorcall_NARGS(nargsf);
    const Py_ssize_t n_names = PyTuple_GET_SIZE(self->names);
    if (nargs < 1 || nargs > 1 + n_names) goto slow;
    /* the call's q, out and form, by position then by keyword; out missing is None */
    PyObject *given[3] = {NULL, NULL, NULL};
    for (Py_ssize_t k = 1; k < nargs; ++k) given[k - 1] = args[k];
    Py_ssize_t n_kw = kwnames == NULL ? 0 : PyTuple_GET_SIZE(kwnames);
    for (Py_ssize_t k = 0; k < n_kw; ++k) {
        PyObject *name = PyTuple_GET_ITEM(kwnames, k);
        Py_ssize_t slot = -1;
        for (Py_ssize_t j = 0; j < n_names && slot < 0; ++j)
            if (name == PyTuple_GET_ITEM(self->names, j)) slot = j;
        if (slot < 0 || given[slot] != NULL) goto slow; /* the fallback says what is wrong */
        given[slot] = args[nargs + k];
    }
    if (given[0] == NULL) goto slow;
    PyObject *kernel = PyObject_GetAttr(args[0], self->attr);
    if (kernel == NULL) return NULL;
    if (Py_IS_TYPE(kernel, &KernelType)) {
        PyObject *run_args[3] = {given[0], given[1] != NULL ? given[1] : Py_None, given[2]};
        Py_ssize_t n_run = given[2] != NULL ? 3 : given[1] != NULL ? 2 : 1;
        PyObject *result = Kernel_run((KernelObject *)kernel, run_args, n_run);
        Py_DECREF(kernel);
        if (result != Py_None) return result; /* the poses, or NULL for an error */
        Py_DECREF(result);
    } else if (PyTuple_CheckExact(kernel) && PyTuple_GET_SIZE(kernel) >= 1 &&
               PyTuple_GET_SIZE(kernel) <= 1 + FAST_MAX_BOUND) {
        /* (fn, *bound): fn(obj, the parameters (None where not given), *bound) */
        PyObject *call[1 + 3 + FAST_MAX_BOUND];
        const Py_ssize_t n_bound = PyTuple_GET_SIZE(kernel) - 1;
        call[0] = args[0];
        for (Py_ssize_t j = 0; j < n_names; ++j) call[1 + j] = given[j] != NULL ? given[j] : Py_None;
        for (Py_ssize_t b = 0; b < n_bound; ++b)
            call[1 + n_names + b] = PyTuple_GET_ITEM(kernel, 1 + b);
        PyObject *result =
            PyObject_Vectorcall(PyTuple_GET_ITEM(kernel, 0), call, 1 + n_names + n_bound, NULL);
        Py_DECREF(kernel);
        if (result != Py_None) return result; /* the answer, or NULL for an error */
        Py_DECREF(result);
    } else {
        Py_DECREF(kernel);
    }
slow:
    return PyObject_Vectorcall(self->fallback, args, nargsf, kwnames);
}

static int FastMethod_init(FastMethodObject *self, PyObject *args, PyObject *kwds) {
    PyObject *attr, *fallback, *names;
    if (!PyArg_ParseTuple(args, "UOO!:FastMethod", &attr, &fallback, &PyTuple_Type, &names))
        return -1;
    const Py_ssize_t n_names = PyTuple_GET_SIZE(names);
    if (!PyCallable_Check(fallback) || n_names < 1 || n_names > 3) {
        PyErr_SetString(PyExc_TypeError, "FastMethod(attr, fallback, names of q[, out[, form]])");
        return -1;
    }
    PyObject *interned = PyTuple_New(n_names);
    if (interned == NULL) return -1;
    for (Py_ssize_t j = 0; j < n_names; ++j) {
        PyObject *name = PyTuple_GET_ITEM(names, j);
        if (!PyUnicode_Check(name)) {
            Py_DECREF(interned);
            PyErr_SetString(PyExc_TypeError, "parameter names must be str");
            return -1;
        }
        Py_INCREF(name);
        PyUnicode_InternInPlace(&name);
        PyTuple_SET_ITEM(interned, j, name);
    }
    Py_INCREF(attr);
    PyUnicode_InternInPlace(&attr);
    Py_XSETREF(self->attr, attr);
    Py_INCREF(fallback);
    Py_XSETREF(self->fallback, fallback);
    Py_XSETREF(self->names, interned);
    self->vectorcall = (vectorcallfunc)FastMethod_vectorcall;
    return 0;
}

/* Accessed on an instance: a bound method (LOAD_METHOD calls skip this; see the flags). */
static PyObject *FastMethod_get(PyObject *self, PyObject *obj, PyObject *Py_UNUSED(type)) {
    if (obj == NULL || obj == Py_None) return Py_NewRef(self);
    return PyMethod_New(self, obj);
}


static int FastMethod_traverse(FastMethodObject *self, visitproc visit, void *arg) {
    Py_VISIT(self->attr);
    Py_VISIT(self->fallback);
    Py_VISIT(self->names);
    Py_VISIT(self->dict);
    return 0;
}

static int FastMethod_clear(FastMethodObject *self) {
    Py_CLEAR(self->attr);
    Py_CLEAR(self->fallback);
    Py_CLEAR(self->names);
    Py_CLEAR(self->dict);
    return 0;
}

static void FastMethod_dealloc(FastMethodObject *self) {
    PyObject_GC_UnTrack(self);
    FastMethod_clear(self);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static PyObject *FastMethod_repr(FastMethodObject *self) {
    return PyUnicode_FromFormat("<fast method %R>", self->fallback);
}

static PyGetSetDef FastMethod_getset[] = {
    {"__dict__", PyObject_GenericGetDict, PyObject_GenericSetDict, NULL, NULL},
    {NULL, NULL, NULL, NULL, NULL},
};

static PyTypeObject FastMethodType = {
    PyVarObject_HEAD_INIT(NULL, 0).tp_name = "poekin.kernel._kernel.FastMethod",
    .tp_basicsize = sizeof(FastMethodObject),
    .tp_dealloc = (destructor)FastMethod_dealloc,
    .tp_vectorcall_offset = offsetof(FastMethodObject, vectorcall),
    .tp_call = PyVectorcall_Call,
    .tp_repr = (reprfunc)FastMethod_repr,
    .tp_flags = Py_TPFLAGS_DEFAULT | Py_TPFLAGS_HAVE_GC | Py_TPFLAGS_HAVE_VECTORCALL |
                Py_TPFLAGS_METHOD_DESCRIPTOR,
    .tp_doc = "A method that runs its object's compiled kernel before any Python (poekin.kernel._fast).",
    .tp_traverse = (traverseproc)FastMethod_traverse,
    .tp_clear = (inquiry)FastMethod_clear,
    .tp_descr_get = FastMethod_get,
    .tp_getset = FastMethod_getset,
    .tp_dictoffset = offsetof(FastMethodObject, dict),
    .tp_init = (initproc)FastMethod_init,
    .tp_new = PyType_GenericNew,
};

/* expose_python(get, call): FastMethod's __get__ and __call__ as Python code sees them (the
 * type's dict), for tools that trace Python and not C: torch.compile's Dynamo traces a descriptor
 * whose type has a Python __get__, and a callable whose type has a Python __call__. get binds the
 * Python fallback, call calls it. The interpreter keeps calling the C slots. */
static PyObject *expose_python(PyObject *Py_UNUSED(mod), PyObject *args) {
    PyObject *get, *call;
    if (!PyArg_ParseTuple(args, "OO:expose_python", &get, &call)) return NULL;
    if (!PyCallable_Check(get) || !PyCallable_Check(call)) {
        PyErr_SetString(PyExc_TypeError, "expose_python(get, call): both must be callable");
        return NULL;
    }
    if (PyDict_SetItemString(FastMethodType.tp_dict, "__get__", get) < 0 ||
        PyDict_SetItemString(FastMethodType.tp_dict, "__call__", call) < 0)
        return NULL;
    PyType_Modified(&FastMethodType);
    Py_RETURN_NONE;
}

/* ------------------------------------------------------------------------------------------ */
/* ik_all(kind, params, T, limits): the compiled twin of poekin.ik.analytic.solve_numpy */

/* Targets per thread below which another thread does not pay for its start. */
#define IK_MIN_PER_THREAD 2048

static void ik_share(void *task) { g_ik_all_task((IkAllTask *)task); }

static void ik_all_run(IkAllTask proto, npy_intp n, int threads) {
    IkAllTask tasks[MAX_THREADS];
    Share shares[MAX_THREADS];
    npy_intp chunk;
    int nt = split_batch(n, IK_MIN_PER_THREAD, threads, &chunk);
    for (int k = 0; k < nt; ++k) {
        tasks[k] = proto;
        tasks[k].lo = k * chunk < n ? k * chunk : n;
        tasks[k].hi = tasks[k].lo + chunk < n ? tasks[k].lo + chunk : n;
        shares[k] = (Share){ik_share, &tasks[k]};
    }
    run_shares(shares, nt);
}

/* A batch smaller than the kernel's width on the narrowest width that holds it: a block costs
 * about the same whatever it holds. Every width gives the same bits. */
static void ik_run_small(IkAllTask task, npy_intp n) {
    task.lo = 0;
    task.hi = n;
#ifdef X86_DISPATCH
    if (n <= 4 && g_lanes >= 4) { /* one target too: AVX2's block runs it faster than SSE2's */
        ik_all_task_4(&task);
        return;
    }
    if (n <= 2) {
        ik_all_task_2(&task);
        return;
    }
#endif
    g_ik_all_task(&task);
}

/* ik_all(kind, params, T, limits[, shaped]) -> (q, valid, bad): q (n, 8, 6) and valid (n, 8)
 * for the n targets of T (a C-contiguous float64 array of shape (..., 4, 4)), or (None, None, i)
 * where target i is not a rigid transform (the caller's validation then says why). shaped
 * (poekin.ik.analytic._quick): q (..., 8, 6) and valid (..., 8) in T's batch shape, and None
 * instead of an error for a T that is not such an array or not rigid transforms. */
/* obj as a C-contiguous float64 array of nd dimensions (a new reference), or NULL with an
 * error: obj itself where it is one already (a one-target call's own cost, issue 26). */
static PyArrayObject *ik_carray(PyObject *obj, int nd) {
    PyArrayObject *a = ik_plain(obj);
    if (a != NULL && PyArray_NDIM(a) == nd) {
        Py_INCREF(a);
        return a;
    }
    return (PyArrayObject *)PyArray_FROMANY(obj, NPY_FLOAT64, nd, nd, NPY_ARRAY_CARRAY_RO);
}

static PyObject *ik_all(PyObject *Py_UNUSED(mod), PyObject *const *args, Py_ssize_t nargs) {
    if (nargs < 4 || nargs > 5) {
        PyErr_SetString(PyExc_TypeError, "ik_all(kind, params, T, limits[, shaped])");
        return NULL;
    }
    const long kind_long = PyLong_AsLong(args[0]);
    if (kind_long == -1 && PyErr_Occurred()) return NULL;
    const int kind = kind_long < INT_MIN || kind_long > INT_MAX ? -1 : (int)kind_long;
    const int shaped = nargs == 5 ? PyObject_IsTrue(args[4]) : 0;
    if (shaped < 0) return NULL;
    PyObject *params_obj = args[1], *T_obj = args[2], *limits_obj = args[3];
    if (shaped) { /* T as the checks below want it, else None: before any conversion */
        PyArrayObject *A = (PyArrayObject *)T_obj;
        if (!PyArray_Check(T_obj) || PyArray_NDIM(A) < 2 || PyArray_NDIM(A) > NPY_MAXDIMS - 1 ||
            PyArray_TYPE(A) != NPY_FLOAT64 || !PyArray_IS_C_CONTIGUOUS(A) ||
            !PyArray_ISALIGNED(A) || PyArray_ISBYTESWAPPED(A) ||
            PyArray_DIM(A, PyArray_NDIM(A) - 1) != 4 || PyArray_DIM(A, PyArray_NDIM(A) - 2) != 4)
            Py_RETURN_NONE;
    }
    PyArrayObject *params = ik_carray(params_obj, 1);
    if (params == NULL) return NULL;
    PyArrayObject *limits = ik_carray(limits_obj, 2);
    if (limits == NULL) {
        Py_DECREF(params);
        return NULL;
    }
    PyArrayObject *T = (PyArrayObject *)T_obj;
    int nd = PyArray_Check(T_obj) ? PyArray_NDIM(T) : 0;
    if (ik_params_size(kind) < 0 || PyArray_DIM(params, 0) != ik_params_size(kind) ||
        PyArray_DIM(limits, 0) != 6 || PyArray_DIM(limits, 1) != 2 || nd < 2 ||
        PyArray_TYPE(T) != NPY_FLOAT64 || !PyArray_IS_C_CONTIGUOUS(T) || !PyArray_ISALIGNED(T) ||
        PyArray_ISBYTESWAPPED(T) || PyArray_DIM(T, nd - 1) != 4 || PyArray_DIM(T, nd - 2) != 4) {
        Py_DECREF(params);
        Py_DECREF(limits);
        PyErr_SetString(PyExc_ValueError,
                        "ik_all(kind, params, T, limits): a known kind with its constants, T a "
                        "C-contiguous float64 (..., 4, 4) array, limits (6, 2)");
        return NULL;
    }
    npy_intp n = PyArray_SIZE(T) / 16;
    const double *Td = PyArray_DATA(T);
    for (npy_intp i = 0; i < n; ++i) {
        if (ik_bad_target(Td + 16 * i)) {
            Py_DECREF(params);
            Py_DECREF(limits);
            if (shaped) Py_RETURN_NONE;
            return Py_BuildValue("(OOn)", Py_None, Py_None, (Py_ssize_t)i);
        }
    }
    npy_intp qdims[NPY_MAXDIMS] = {n, 8, 6}, vdims[NPY_MAXDIMS] = {n, 8};
    int qnd = 3, vnd = 2;
    if (shaped) { /* T's batch axes, then (8, 6) and (8) */
        qnd = vnd = nd - 2;
        for (int i = 0; i < nd - 2; ++i) qdims[i] = vdims[i] = PyArray_DIM(T, i);
        qdims[qnd++] = 8, qdims[qnd++] = 6, vdims[vnd++] = 8;
    }
    PyArrayObject *q = (PyArrayObject *)PyArray_SimpleNew(qnd, qdims, NPY_FLOAT64);
    PyArrayObject *valid = (PyArrayObject *)PyArray_SimpleNew(vnd, vdims, NPY_BOOL);
    if (q == NULL || valid == NULL) {
        Py_XDECREF(q);
        Py_XDECREF(valid);
        Py_DECREF(params);
        Py_DECREF(limits);
        return NULL;
    }
    if (n > 0) {
        IkAllTask proto = {kind, PyArray_DATA(params), Td, PyArray_DATA(limits), PyArray_DATA(q),
                        PyArray_DATA(valid), 0, 0};
        if (n >= 64) {
            int threads = g_threads;
            Py_BEGIN_ALLOW_THREADS ik_all_run(proto, n, threads);
            Py_END_ALLOW_THREADS
        } else if (n < g_lanes) {
            ik_run_small(proto, n);
        } else {
            ik_all_run(proto, n, 1);
        }
    }
    Py_DECREF(params);
    Py_DECREF(limits);
    PyObject *result = PyTuple_New(3), *none = PyLong_FromLong(-1);
    if (result == NULL || none == NULL) {
        Py_XDECREF(result);
        Py_XDECREF(none);
        Py_DECREF(q);
        Py_DECREF(valid);
        return NULL;
    }
    PyTuple_SET_ITEM(result, 0, (PyObject *)q);
    PyTuple_SET_ITEM(result, 1, (PyObject *)valid);
    PyTuple_SET_ITEM(result, 2, none);
    return result;
}

/* quick_ik_all(chain, T, near, kind, params, limits, geometry, result): Chain.ik_all(T) with
 * every other argument at its default, on a chain of an exact geometry, as
 * poekin.ik.analytic arms it (the chain's _ik_all_quick, which FastMethod calls): the class
 * `result` (IKSolutions) of ik_all(kind, params, T, limits, True)'s q and valid, the geometry,
 * the chain and T; None where that needs the usual path (near given, or ik_all's None). */
static PyObject *quick_ik_all(PyObject *mod, PyObject *const *args, Py_ssize_t nargs) {
    static const char *names[5] = {"q", "valid", "geometry", "_chain", "_targets"};
    static PyObject *interned[5];
    if (nargs != 8) {
        PyErr_SetString(PyExc_TypeError,
                        "quick_ik_all(chain, T, near, kind, params, limits, geometry, result)");
        return NULL;
    }
    if (args[2] != Py_None) Py_RETURN_NONE;
    if (ik_intern(names, interned, 5) < 0) return NULL;
    PyObject *all_args[5] = {args[3], args[4], args[1], args[5], Py_True};
    PyObject *done = ik_all(mod, all_args, 5);
    if (done == NULL || done == Py_None) return done;
    PyObject *values[5] = {Py_NewRef(PyTuple_GET_ITEM(done, 0)), Py_NewRef(PyTuple_GET_ITEM(done, 1)),
                           Py_NewRef(args[6]), Py_NewRef(args[0]), Py_NewRef(args[1])};
    Py_DECREF(done);
    return ik_new_result(args[7], interned, values, 5);
}

/* ------------------------------------------------------------------------------------------ */
/* distance and pair_distances: the compiled twin of poekin.collision.gjk.distance */

#include "_distance.h"

/* pair_distances skips a pair that a bound puts beyond its cutoff by this (m): a pair nearer
 * than that is measured, so that no rounding, in the bound or in the distance, decides whether
 * it comes out measured or not (the reference measures every pair) */
#define DG_BROAD_SLACK 1e-6

/* Pairs per thread below which another thread does not pay for its start. */
#define DG_MIN_PER_THREAD 1024

/* N pairs (kind1 T1[i] S1[i], kind2 T2[i] S2[i]) in [lo, hi), or (pairs set) configurations
 * [lo, hi) of G geoms, each geom g posed by frames[frame_of[g]] @ local[g] (frames
 * (B, F, 4, 4); local[g] alone where frame_of[g] < 0; frames[g] where local is NULL), P pairs
 * of them each. */
typedef struct {
    DgOptions opt;
    npy_intp lo, hi;
    int kind[2];
    const double *T[2], *S[2], *V[2];
    npy_intp nv[2];
    const int32_t *types, *pairs, *mesh_adr, *mesh_num, *frame_of;
    const double *sizes, *mesh_vert, *frames, *local, *radii;
    double cutoff; /* pairs: at or beyond it not reported, and not measured where a bound
                    * (dg_beyond) puts them beyond it by DG_BROAD_SLACK */
    npy_intp G, P, F;
    double *dist, *pts;
    npy_bool *hit; /* set: whether each configuration has a pair nearer than cutoff, no more */
    const int64_t *groups; /* set: the configurations of group i are [groups[i], groups[i + 1]) */
    const Program *fk;     /* set: frames is NULL, each configuration's frames are fk's of qpos */
    const double *qpos;    /* with fk: (B, nq) */
    int64_t *first;        /* with groups: each group's first configuration clear of cutoff */
    int failed;
} DgTask;

static void dg_task(void *arg) {
    DgTask *t = (DgTask *)arg;
    DgWork W;
    memset(&W, 0, sizeof W);
    DgShape A, B;
    for (npy_intp i = t->lo; i < t->hi; ++i) {
        dg_shape(&A, t->kind[0], t->T[0] + 16 * i, t->V[0] ? DG_ZERO : t->S[0] + 3 * i, t->V[0],
                 t->nv[0]);
        dg_shape(&B, t->kind[1], t->T[1] + 16 * i, t->V[1] ? DG_ZERO : t->S[1] + 3 * i, t->V[1],
                 t->nv[1]);
        if (dg_distance(&A, &B, &t->opt, &W, t->dist + i, t->pts + 6 * i) < 0) {
            t->failed = 1;
            break;
        }
    }
    dg_free_work(&W);
}

/* out = F @ L, 4x4 row-major, each entry's four products summed in order (the reference's
 * gjk.compose), but for the last row (0 0 0 1 for rigid transforms), which no distance reads:
 * not computed */
static void dg_compose(const double *F, const double *L, double *out) {
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 4; ++j)
            out[4 * i + j] = F[4 * i] * L[j] + F[4 * i + 1] * L[4 + j] +
                             F[4 * i + 2] * L[8 + j] + F[4 * i + 3] * L[12 + j];
}

/* whether dg_distance measures the pair of kinds (ka, kb) in closed form */
static int dg_closed_pair(int ka, int kb) {
    if (ka == DG_PLANE || kb == DG_PLANE) return 1;
    if (ka == DG_CAPSULE && kb == DG_CAPSULE) return 1;
    for (int k = 0; k < 2; ++k) {
        int s = k ? kb : ka, o = k ? ka : kb;
        if (s == DG_SPHERE && (o == DG_SPHERE || o == DG_CAPSULE || o == DG_BOX || o == DG_CYLINDER))
            return 1;
    }
    return 0;
}

/* a bound below the distance between the box X and the shape Y: the box lies in the half-space
 * behind each of its faces, and Y's distance to a half-space is its support's (the largest of
 * the six; exact where a face is nearest, as for a tool above a table) */
static double dg_box_faces(const DgShape *X, const DgShape *Y) {
    double best = -INFINITY, c[3], n[3], m[3], s[3];
    dg_origin(X->T, c);
    if (Y->kind == DG_SPHERE || Y->kind == DG_CAPSULE || Y->kind == DG_CYLINDER) {
        /* a segment, or a disc swept along one: its centre and axis in X's frame; along the
         * box's axis i it reaches h |u_i| from its centre, and a capsule's radius r more, a
         * cylinder's r sqrt(1 - u_i^2) (its disc's reach) */
        double p[3], u[3], d[3], lc[3], lu[3];
        double h = Y->kind == DG_SPHERE ? 0.0 : Y->size[1];
        dg_origin(Y->T, p);
        dg_column(Y->T, 2, u);
        dg_sub(p, c, d);
        dg_to_local(X->T, d, lc);
        dg_to_local(X->T, u, lu);
        for (int i = 0; i < 3; ++i) {
            double reach = h * fabs(lu[i]) +
                           (Y->kind == DG_CYLINDER ? Y->size[0] * sqrt(dg_max(1.0 - lu[i] * lu[i], 0.0))
                                                   : Y->radius);
            double gap = dg_max(lc[i] - reach, -lc[i] - reach) - X->size[i];
            best = gap > best ? gap : best;
        }
        return best;
    }
    for (int i = 0; i < 3; ++i)
        for (int k = 0; k < 2; ++k) {
            dg_column(X->T, i, n);
            if (k) n[0] = -n[0], n[1] = -n[1], n[2] = -n[2];
            m[0] = -n[0], m[1] = -n[1], m[2] = -n[2];
            dg_support(Y, m, s);
            double gap = dg_dot(n, s) - Y->radius - (dg_dot(n, c) + X->size[i]);
            best = gap > best ? gap : best;
        }
    return best;
}

/* whether the pair (A, B) lies farther apart than cutoff by DG_BROAD_SLACK, by bounds below its
 * distance: the bounding spheres (radii ra, rb); then, for a pair GJK would measure, a box's
 * faces (dg_box_faces), each shape of a closed form with a sphere against the other's bounding
 * sphere, and a cylinder with a capsule or a cylinder as the capsule of its radius and
 * half-length, which holds it */
static int dg_beyond(const DgShape *A, const DgShape *B, double ra, double rb, double cutoff,
                     const DgOptions *opt, DgWork *W) {
    double limit = cutoff + DG_BROAD_SLACK;
    double dx = A->T[3] - B->T[3], dy = A->T[7] - B->T[7], dz = A->T[11] - B->T[11];
    double reach = ra + rb + limit; /* the centres farther apart than this: beyond (squared, no
                                     * sqrt: a bound, so rounding moves only its slack) */
    if (reach < 0.0 || dx * dx + dy * dy + dz * dz > reach * reach) return 1;
    int ka = A->kind, kb = B->kind;
    if (dg_closed_pair(ka, kb)) return 0;
    if ((ka == DG_BOX && dg_box_faces(A, B) > limit) || (kb == DG_BOX && dg_box_faces(B, A) > limit))
        return 1;
    double d, pts[6];
    for (int k = 0; k < 2; ++k) {
        const DgShape *X = k ? B : A, *Y = k ? A : B;
        double r = k ? ra : rb;
        int kx = X->kind;
        if (!(kx == DG_CAPSULE || kx == DG_BOX || kx == DG_CYLINDER) || !(r < INFINITY)) continue;
        double size[3] = {r, 0.0, 0.0};
        DgShape S;
        dg_shape(&S, DG_SPHERE, Y->T, size, NULL, 0);
        if (dg_distance(&S, X, opt, W, &d, pts) < 0) return 0; /* out of memory: measure it */
        if (d > limit) return 1;
    }
    if ((ka == DG_CYLINDER || kb == DG_CYLINDER) && (ka == DG_CAPSULE || ka == DG_CYLINDER) &&
        (kb == DG_CAPSULE || kb == DG_CYLINDER)) {
        DgShape a = *A, b = *B;
        a.kind = b.kind = DG_CAPSULE;
        a.radius = A->size[0], b.radius = B->size[0];
        dg_capsule_capsule(&a, &b, &d, pts);
        return d > limit;
    }
    return 0;
}

/* configuration c of the task: its geoms posed (posed: room for G poses), then its pairs
 * measured (the task's dist and pts) or, in hit mode, looked at up to the first nearer than
 * cutoff, its frames (F, 4, 4) at frames; in hit mode 1 where a pair is nearer than cutoff,
 * else 0; -1 out of memory */
static int dg_config(const DgTask *t, npy_intp c, const double *frames, double *posed,
                     DgWork *W) {
    if (t->local)
        for (npy_intp g = 0; g < t->G; ++g) {
            if (t->frame_of[g] < 0)
                memcpy(posed + 16 * g, t->local + 16 * g, 16 * sizeof(double));
            else
                dg_compose(frames + 16 * (npy_intp)t->frame_of[g], t->local + 16 * g,
                           posed + 16 * g);
        }
    const double *pose = t->local ? posed : frames;
    DgShape A, B;
    double dist, pts[6];
    for (npy_intp p = 0; p < t->P; ++p) {
        int32_t g1 = t->pairs[2 * p], g2 = t->pairs[2 * p + 1];
        int mesh1 = t->types[g1] == DG_MESH, mesh2 = t->types[g2] == DG_MESH;
        dg_shape(&A, t->types[g1], pose + 16 * g1, t->sizes + 3 * g1,
                 mesh1 ? t->mesh_vert + 3 * (npy_intp)t->mesh_adr[g1] : NULL,
                 mesh1 ? t->mesh_num[g1] : 0);
        dg_shape(&B, t->types[g2], pose + 16 * g2, t->sizes + 3 * g2,
                 mesh2 ? t->mesh_vert + 3 * (npy_intp)t->mesh_adr[g2] : NULL,
                 mesh2 ? t->mesh_num[g2] : 0);
        int measured = !(t->cutoff < INFINITY &&
                         dg_beyond(&A, &B, t->radii[g1], t->radii[g2], t->cutoff, &t->opt, W));
        if (measured && dg_distance(&A, &B, &t->opt, W, &dist, pts) < 0) return -1;
        int near = measured && dist < t->cutoff;
        if (t->hit || t->groups) {
            if (near) return 1;
            continue;
        }
        npy_intp i = c * t->P + p;
        t->dist[i] = near ? dist : INFINITY;
        for (int k = 0; k < 6; ++k) t->pts[6 * i + k] = near ? pts[k] : NAN;
    }
    return 0;
}

/* The frames (F, 4, 4) of configuration c of the task: frames' own, or with fk those the FK
 * program computes in buf, a block of up to g_lanes configurations [c, end) at a time (block:
 * the configurations buf holds, [block[0], block[1])); NULL where memory ran out. */
static const double *dg_frames(const DgTask *t, npy_intp c, npy_intp end, double *buf,
                               npy_intp block[2]) {
    if (!t->fk) return t->frames + 16 * t->F * c;
    if (c < block[0] || c >= block[1]) {
        npy_intp m = end - c < g_lanes ? end - c : g_lanes;
        Task task = {t->fk, t->qpos + c * t->fk->nq, buf, 0, m, FORM_4X4, 0};
        g_run_task(&task);
        if (task.bad) return NULL; /* out of memory (qpos was checked finite) */
        block[0] = c, block[1] = c + m;
    }
    return buf + 16 * t->F * (c - block[0]);
}

/* the task's configurations [lo, hi), or with groups its groups [lo, hi): each group's
 * configurations in order up to the first with no pair nearer than cutoff (first: its index,
 * -1 where there is none) */
static void dg_pairs_task(void *arg) {
    DgTask *t = (DgTask *)arg;
    DgWork W;
    memset(&W, 0, sizeof W);
    double *posed = t->local ? calloc(16 * (size_t)(t->G > 0 ? t->G : 1), sizeof(double)) : NULL;
    if (t->local && posed == NULL) {
        t->failed = 1;
        return;
    }
    double *buf = t->fk ? malloc(sizeof(double) * 16 * (size_t)(g_lanes * t->F)) : NULL;
    if (t->fk && buf == NULL) t->failed = 1;
    npy_intp block[2] = {0, 0};
    for (npy_intp i = t->lo; i < t->hi && !t->failed; ++i) {
        if (t->groups) {
            t->first[i] = -1;
            for (npy_intp c = t->groups[i]; c < t->groups[i + 1]; ++c) {
                const double *frames = dg_frames(t, c, t->groups[i + 1], buf, block);
                int r = frames ? dg_config(t, c, frames, posed, &W) : -1;
                if (r < 0) t->failed = 1;
                if (r <= 0) {
                    t->first[i] = r == 0 ? c : -1;
                    break;
                }
            }
        } else {
            const double *frames = dg_frames(t, i, t->hi, buf, block);
            int r = frames ? dg_config(t, i, frames, posed, &W) : -1;
            if (r < 0) t->failed = 1;
            else if (t->hit) t->hit[i] = (npy_bool)r;
        }
    }
    free(buf);
    free(posed);
    dg_free_work(&W);
}

/* run the task on n items (pairs, or configurations of `per` pairs each), on up to g_threads
 * threads; -1 out of memory */
static int dg_run(DgTask proto, npy_intp n, npy_intp per) {
    DgTask tasks[MAX_THREADS];
    Share shares[MAX_THREADS];
    npy_intp chunk;
    per = per > 0 ? per : 1;
    int nt = split_batch(n, (DG_MIN_PER_THREAD + per - 1) / per, g_threads, &chunk);
    for (int k = 0; k < nt; ++k) {
        tasks[k] = proto;
        tasks[k].lo = k * chunk < n ? k * chunk : n;
        tasks[k].hi = tasks[k].lo + chunk < n ? tasks[k].lo + chunk : n;
        shares[k] = (Share){proto.pairs ? dg_pairs_task : dg_task, &tasks[k]};
    }
    if (n * per >= MIN_CONFIGS_NO_GIL) {
        Py_BEGIN_ALLOW_THREADS run_shares(shares, nt);
        Py_END_ALLOW_THREADS
    } else {
        run_shares(shares, nt);
    }
    for (int k = 0; k < nt; ++k)
        if (tasks[k].failed) return -1;
    return 0;
}

/* a C-contiguous, aligned, native float64 (or int32) array of nd dimensions, the last ones
 * `tail` (-1: any) */
static int dg_array(PyObject *o, int type, int nd, npy_intp t1, npy_intp t2) {
    if (!PyArray_Check(o)) return 0;
    PyArrayObject *a = (PyArrayObject *)o;
    if (PyArray_TYPE(a) != type || !PyArray_IS_C_CONTIGUOUS(a) || !PyArray_ISALIGNED(a) ||
        PyArray_ISBYTESWAPPED(a) || PyArray_NDIM(a) != nd)
        return 0;
    if (t2 >= 0 && PyArray_DIM(a, nd - 1) != t2) return 0;
    if (t1 >= 0 && PyArray_DIM(a, nd - 2) != t1) return 0;
    return 1;
}

static int dg_known(int kind) {
    return kind == DG_PLANE || (kind >= DG_SPHERE && kind <= DG_MESH);
}

static int dg_options(PyObject *o, DgOptions *opt) {
    return PyArg_ParseTuple(o, "didiii", &opt->tol, &opt->max_iter, &opt->epa_tol,
                            &opt->epa_faces, &opt->depth, &opt->closed);
}

static PyObject *dg_result(npy_intp nd, const npy_intp *dims, PyArrayObject **dist,
                           PyArrayObject **pts) {
    npy_intp pdims[NPY_MAXDIMS];
    for (int i = 0; i < nd; ++i) pdims[i] = dims[i];
    pdims[nd] = 2, pdims[nd + 1] = 3;
    *dist = (PyArrayObject *)PyArray_SimpleNew((int)nd, (npy_intp *)dims, NPY_FLOAT64);
    *pts = (PyArrayObject *)PyArray_SimpleNew((int)nd + 2, pdims, NPY_FLOAT64);
    if (*dist == NULL || *pts == NULL) {
        Py_XDECREF(*dist);
        Py_XDECREF(*pts);
        return NULL;
    }
    return Py_None;
}

/* distance(kind1, T1, S1, kind2, T2, S2, options) -> (dist (N,), points (N, 2, 3)): kinds
 * MuJoCo's geom types (not two planes), T (N, 4, 4), S (N, 3) sizes or a mesh's vertices
 * (V, 3), options (tol, max_iter, epa_tol, epa_faces, depth, closed: 0 for gjk.gjk); the arrays
 * C-contiguous float64 */
static PyObject *distance(PyObject *Py_UNUSED(mod), PyObject *args) {
    DgTask t;
    memset(&t, 0, sizeof t);
    PyObject *pose1, *size1, *pose2, *size2, *options;
    if (!PyArg_ParseTuple(args, "iOOiOOO", &t.kind[0], &pose1, &size1, &t.kind[1], &pose2, &size2,
                          &options) ||
        !dg_options(options, &t.opt))
        return NULL;
    PyObject *T[2] = {pose1, pose2}, *S[2] = {size1, size2};
    npy_intp n = -1;
    for (int k = 0; k < 2; ++k) {
        int mesh = t.kind[k] == DG_MESH;
        if (!dg_known(t.kind[k]) || !dg_array(T[k], NPY_FLOAT64, 3, 4, 4) ||
            !dg_array(S[k], NPY_FLOAT64, 2, -1, 3) ||
            (k == 1 && PyArray_DIM((PyArrayObject *)T[k], 0) != n) ||
            (!mesh && PyArray_DIM((PyArrayObject *)S[k], 0) !=
                          PyArray_DIM((PyArrayObject *)T[k], 0)) ||
            (mesh && PyArray_DIM((PyArrayObject *)S[k], 0) == 0)) {
            PyErr_SetString(PyExc_ValueError,
                            "distance(kind1, T1, S1, kind2, T2, S2, options): known kinds, T "
                            "(N, 4, 4), S (N, 3) or a mesh's (V, 3), C-contiguous float64");
            return NULL;
        }
        n = PyArray_DIM((PyArrayObject *)T[k], 0);
        t.T[k] = PyArray_DATA((PyArrayObject *)T[k]);
        t.S[k] = PyArray_DATA((PyArrayObject *)S[k]);
        t.V[k] = mesh ? t.S[k] : NULL;
        t.nv[k] = mesh ? PyArray_DIM((PyArrayObject *)S[k], 0) : 0;
    }
    if (t.kind[0] == DG_PLANE && t.kind[1] == DG_PLANE) {
        PyErr_SetString(PyExc_ValueError, "distance: two planes");
        return NULL;
    }
    PyArrayObject *dist, *pts;
    if (dg_result(1, &n, &dist, &pts) == NULL) return NULL;
    t.dist = PyArray_DATA(dist), t.pts = PyArray_DATA(pts);
    if (dg_run(t, n, 1) < 0) {
        Py_DECREF(dist);
        Py_DECREF(pts);
        return PyErr_NoMemory();
    }
    return Py_BuildValue("(NN)", dist, pts);
}

/* pair_distances(types, sizes, mesh_adr, mesh_num, mesh_vert, pairs, frames, frame_of, local,
 * options, radii, cutoff, hit) -> (dist (B, P), points (B, P, 2, 3)), or with hit true
 * hit (B,) bool: G geoms of MuJoCo's types (int32 (G,)) and sizes (G, 3), meshes as vertices
 * mesh_vert[mesh_adr[g]:][:mesh_num[g]] ((V, 3)), the P pairs (int32 (P, 2), geom indices, not
 * two planes), posed by frames (B, F, 4, 4) (or (kernel, qpos): an FK Kernel's frames of
 * qpos (B, nq), computed as needed), frame_of (int32 (G,), -1: none) and local
 * (G, 4, 4) (None: frames are the geoms' poses, F = G; dg_pairs_task); a pair at cutoff or
 * beyond comes out inf (points NaN), and is not measured where a bound rules it out
 * (dg_beyond, radii (G,) the bounding spheres'); hit: whether some pair is nearer than cutoff;
 * groups (int64 (N + 1,) offsets, with hit): first (N,) int64, each group's first configuration
 * with no pair nearer than cutoff (-1: none), those after it not looked at */
static PyObject *pair_distances(PyObject *Py_UNUSED(mod), PyObject *args) {
    DgTask t;
    memset(&t, 0, sizeof t);
    PyObject *types, *sizes, *adr, *num, *vert, *pairs, *frames, *frame_of, *local, *options,
        *radii, *groups = Py_None;
    int hit;
    if (!PyArg_ParseTuple(args, "OOOOOOOOOOOdp|O", &types, &sizes, &adr, &num, &vert, &pairs,
                          &frames, &frame_of, &local, &options, &radii, &t.cutoff, &hit,
                          &groups) ||
        !dg_options(options, &t.opt))
        return NULL;
    npy_intp B = -1, F = 0; /* configurations, frames of each */
    if (PyTuple_Check(frames) && PyTuple_GET_SIZE(frames) == 2 &&
        Py_IS_TYPE(PyTuple_GET_ITEM(frames, 0), &KernelType)) { /* (FK kernel, qpos (B, nq)) */
        const Program *prog = &((KernelObject *)PyTuple_GET_ITEM(frames, 0))->prog;
        PyObject *qpos = PyTuple_GET_ITEM(frames, 1);
        if (prog->jac_cols == 0 && dg_array(qpos, NPY_FLOAT64, 2, -1, prog->nq)) {
            t.fk = prog, t.qpos = PyArray_DATA((PyArrayObject *)qpos);
            B = PyArray_DIM((PyArrayObject *)qpos, 0), F = prog->n_out;
            for (npy_intp i = 0; i < B * prog->nq && B >= 0; ++i)
                if (!isfinite(t.qpos[i])) B = -1;
        }
    } else if (dg_array(frames, NPY_FLOAT64, 4, 4, 4)) {
        B = PyArray_DIM((PyArrayObject *)frames, 0), F = PyArray_DIM((PyArrayObject *)frames, 1);
        t.frames = PyArray_DATA((PyArrayObject *)frames);
    }
    int ok = dg_array(types, NPY_INT32, 1, -1, -1) && dg_array(sizes, NPY_FLOAT64, 2, -1, 3) &&
             dg_array(adr, NPY_INT32, 1, -1, -1) && dg_array(num, NPY_INT32, 1, -1, -1) &&
             dg_array(vert, NPY_FLOAT64, 2, -1, 3) && dg_array(pairs, NPY_INT32, 2, -1, 2) &&
             B >= 0 && dg_array(frame_of, NPY_INT32, 1, -1, -1) &&
             (local == Py_None || dg_array(local, NPY_FLOAT64, 3, 4, 4)) &&
             dg_array(radii, NPY_FLOAT64, 1, -1, -1) && !isnan(t.cutoff);
    npy_intp G = ok ? PyArray_DIM((PyArrayObject *)types, 0) : 0;
    if (ok)
        ok = PyArray_DIM((PyArrayObject *)sizes, 0) == G &&
             PyArray_DIM((PyArrayObject *)radii, 0) == G &&
             PyArray_DIM((PyArrayObject *)adr, 0) == G &&
             PyArray_DIM((PyArrayObject *)num, 0) == G &&
             PyArray_DIM((PyArrayObject *)frame_of, 0) == G &&
             (local == Py_None ? F == G : PyArray_DIM((PyArrayObject *)local, 0) == G);
    if (ok) {
        t.types = PyArray_DATA((PyArrayObject *)types);
        t.mesh_adr = PyArray_DATA((PyArrayObject *)adr);
        t.mesh_num = PyArray_DATA((PyArrayObject *)num);
        t.pairs = PyArray_DATA((PyArrayObject *)pairs);
        t.frame_of = PyArray_DATA((PyArrayObject *)frame_of);
        npy_intp V = PyArray_DIM((PyArrayObject *)vert, 0);
        for (npy_intp g = 0; g < G && ok; ++g) {
            ok = t.frame_of[g] < F && (local != Py_None || t.frame_of[g] == g);
            if (t.types[g] == DG_MESH)
                ok = ok && t.mesh_adr[g] >= 0 && t.mesh_num[g] > 0 &&
                     (npy_intp)t.mesh_adr[g] + t.mesh_num[g] <= V;
        }
        npy_intp P = PyArray_DIM((PyArrayObject *)pairs, 0);
        for (npy_intp p = 0; p < P && ok; ++p) {
            int32_t a = t.pairs[2 * p], b = t.pairs[2 * p + 1];
            ok = a >= 0 && a < G && b >= 0 && b < G && dg_known(t.types[a]) &&
                 dg_known(t.types[b]) && !(t.types[a] == DG_PLANE && t.types[b] == DG_PLANE);
        }
    }
    if (!ok) {
        PyErr_SetString(PyExc_ValueError,
                        "pair_distances: int32 types (G,), float64 sizes (G, 3), int32 mesh_adr "
                        "and mesh_num (G,), mesh_vert (V, 3), int32 pairs (P, 2) of geoms of "
                        "known types (not two planes), frames (B, F, 4, 4) or (an FK Kernel, "
                        "finite qpos (B, nq)), int32 frame_of (G,) below F, local (G, 4, 4) or "
                        "None (frame_of the geoms, F = G), radii (G,), C-contiguous, and a "
                        "cutoff not NaN");
        return NULL;
    }
    t.sizes = PyArray_DATA((PyArrayObject *)sizes);
    t.mesh_vert = PyArray_DATA((PyArrayObject *)vert);
    t.local = local == Py_None ? NULL : PyArray_DATA((PyArrayObject *)local);
    t.radii = PyArray_DATA((PyArrayObject *)radii);
    t.G = G, t.F = F;
    t.P = PyArray_DIM((PyArrayObject *)pairs, 0);
    npy_intp dims[2] = {B, t.P};
    if (groups != Py_None) { /* each group's first configuration clear of cutoff */
        npy_intp n = dg_array(groups, NPY_INT64, 1, -1, -1)
                         ? PyArray_DIM((PyArrayObject *)groups, 0) - 1
                         : -1;
        const int64_t *g = n >= 0 ? PyArray_DATA((PyArrayObject *)groups) : NULL;
        int fits = hit && n >= 0 && g[0] >= 0 && g[n] <= dims[0];
        for (npy_intp i = 0; i < n && fits; ++i) fits = g[i] <= g[i + 1];
        if (!fits) {
            PyErr_SetString(PyExc_ValueError,
                            "pair_distances: groups must be int64 (N + 1,) offsets, from 0 or "
                            "more, nondecreasing, to at most B, with hit true");
            return NULL;
        }
        PyArrayObject *out = (PyArrayObject *)PyArray_SimpleNew(1, &n, NPY_INT64);
        if (out == NULL) return NULL;
        t.groups = g, t.first = PyArray_DATA(out);
        npy_intp per = n > 0 ? t.P * ((g[n] - g[0]) / n + 1) : t.P;
        if (dg_run(t, n, per) < 0) {
            Py_DECREF(out);
            return PyErr_NoMemory();
        }
        return (PyObject *)out;
    }
    if (hit) {
        PyArrayObject *out = (PyArrayObject *)PyArray_SimpleNew(1, dims, NPY_BOOL);
        if (out == NULL) return NULL;
        t.hit = PyArray_DATA(out);
        if (dg_run(t, dims[0], t.P) < 0) {
            Py_DECREF(out);
            return PyErr_NoMemory();
        }
        return (PyObject *)out;
    }
    PyArrayObject *dist, *pts;
    if (dg_result(2, dims, &dist, &pts) == NULL) return NULL;
    t.dist = PyArray_DATA(dist), t.pts = PyArray_DATA(pts);
    if (dg_run(t, dims[0], t.P) < 0) {
        Py_DECREF(dist);
        Py_DECREF(pts);
        return PyErr_NoMemory();
    }
    return Py_BuildValue("(NN)", dist, pts);
}

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

/* set_width(n): the kernel's vector width, 0 for the widest this CPU runs (tests use it) */
static PyObject *set_width(PyObject *Py_UNUSED(mod), PyObject *arg) {
    long n = PyLong_AsLong(arg);
    if (n == -1 && PyErr_Occurred()) return NULL;
    if (n < 0 || n > 8 || choose_width((int)n) < 0) {
        PyErr_Format(PyExc_ValueError, "width %ld is not one this CPU runs", n);
        return NULL;
    }
    return PyLong_FromLong(g_lanes);
}

static PyObject *get_width(PyObject *Py_UNUSED(mod), PyObject *Py_UNUSED(unused)) {
    return PyLong_FromLong(g_lanes);
}

static PyObject *get_threads(PyObject *Py_UNUSED(mod), PyObject *Py_UNUSED(unused)) {
    return PyLong_FromLong(g_threads);
}

/* ------------------------------------------------------------------------------------------ */
/* ordered: the compiled twin of poekin.ik.analytic.order_numpy */

/* t rounded to the nearest integer, a half to the even one (numpy.round; nearbyint's, without
 * its cost of saving the floating-point environment): below 2^52, adding and taking away 2^52
 * leaves the rounded value; from 2^52 on (and NaN) t is its own */
static inline double ik_round_even(double t) {
    double r = copysign((fabs(t) + 0x1p52) - 0x1p52, t);
    return fabs(t) < 0x1p52 ? r : t;
}

/* a branch's place in the order as an integer: the invalid after the valid (the top bit),
 * then by the squared distance d2 >= 0 (whose bits, as an integer, order as it does), NaN
 * last (as NumPy sorts) */
static inline uint64_t ik_sort_key(int valid, double d2) {
    uint64_t bits;
    memcpy(&bits, &d2, sizeof bits);
    bits = isnan(d2) ? 0x7ff8000000000000ULL : bits;
    return ((uint64_t)!valid << 63) | bits;
}

/* ordered(q, valid, ref, limits, revolute) -> (q, valid): q (N, K, J) float64 and valid (N, K)
 * bool, each branch's revolute angles moved by whole turns to the equivalents nearest
 * ref (N, J) within limits (J, 2) (poekin.ik._angles.nearest_turns), and the K branches of each
 * target sorted, stably, the valid first, then by the squared distance to ref summed joint by
 * joint in order; revolute (J,) bool */
static PyObject *ordered(PyObject *Py_UNUSED(mod), PyObject *args) {
    PyObject *q_obj, *valid_obj, *ref_obj, *limits_obj, *rev_obj;
    if (!PyArg_ParseTuple(args, "OOOOO:ordered", &q_obj, &valid_obj, &ref_obj, &limits_obj,
                          &rev_obj))
        return NULL;
    if (!dg_array(q_obj, NPY_FLOAT64, 3, -1, -1) || !dg_array(valid_obj, NPY_BOOL, 2, -1, -1) ||
        !dg_array(ref_obj, NPY_FLOAT64, 2, -1, -1) ||
        !dg_array(limits_obj, NPY_FLOAT64, 2, -1, 2) || !dg_array(rev_obj, NPY_BOOL, 1, -1, -1)) {
        PyErr_SetString(PyExc_ValueError,
                        "ordered(q, valid, ref, limits, revolute): C-contiguous q (N, K, J) "
                        "float64, valid (N, K) bool, ref (N, J), limits (J, 2), revolute (J,) bool");
        return NULL;
    }
    PyArrayObject *Q = (PyArrayObject *)q_obj, *V = (PyArrayObject *)valid_obj;
    PyArrayObject *R = (PyArrayObject *)ref_obj, *L = (PyArrayObject *)limits_obj;
    PyArrayObject *Rv = (PyArrayObject *)rev_obj;
    npy_intp N = PyArray_DIM(Q, 0), K = PyArray_DIM(Q, 1), J = PyArray_DIM(Q, 2);
    if (PyArray_DIM(V, 0) != N || PyArray_DIM(V, 1) != K || PyArray_DIM(R, 0) != N ||
        PyArray_DIM(R, 1) != J || PyArray_DIM(L, 0) != J || PyArray_DIM(Rv, 0) != J) {
        PyErr_SetString(PyExc_ValueError, "ordered: the shapes of q, valid, ref, limits and "
                                          "revolute do not agree");
        return NULL;
    }
    PyArrayObject *q_out = (PyArrayObject *)PyArray_SimpleNew(3, PyArray_DIMS(Q), NPY_FLOAT64);
    PyArrayObject *v_out = (PyArrayObject *)PyArray_SimpleNew(2, PyArray_DIMS(V), NPY_BOOL);
    double *moved = malloc(sizeof(double) * (size_t)(K * J > 0 ? K * J : 1));
    uint64_t *key = malloc(sizeof(uint64_t) * (size_t)(K > 0 ? K : 1));
    npy_intp *order = malloc(sizeof(npy_intp) * (size_t)(K > 0 ? K : 1));
    if (q_out == NULL || v_out == NULL || moved == NULL || key == NULL || order == NULL) {
        Py_XDECREF(q_out);
        Py_XDECREF(v_out);
        free(moved), free(key), free(order);
        return PyErr_NoMemory();
    }
    const double *q = PyArray_DATA(Q), *ref = PyArray_DATA(R), *lim = PyArray_DATA(L);
    const npy_bool *valid = PyArray_DATA(V), *rev = PyArray_DATA(Rv);
    double *qo = PyArray_DATA(q_out);
    npy_bool *vo = PyArray_DATA(v_out);
    for (npy_intp i = 0; i < N; ++i) {
        const double *r = ref + J * i;
        for (npy_intp b = 0; b < K; ++b) {
            const double *x = q + (i * K + b) * J;
            double *m = moved + b * J, sum = 0.0;
            for (npy_intp j = 0; j < J; ++j) {
                double t = (r[j] - x[j]) / IK_TWO_PI;
                m[j] = x[j];
                /* within the limits and half a turn of ref: no turn moves it (k = 0 below) */
                int stays = (x[j] >= lim[2 * j]) & (x[j] <= lim[2 * j + 1]) & (fabs(t) < 0.5);
                if (rev[j] && !stays) { /* nearest_turns: the nearest turns, within the limits */
                    double fewest = ceil((lim[2 * j] - x[j]) / IK_TWO_PI);
                    double most = floor((lim[2 * j + 1] - x[j]) / IK_TWO_PI);
                    double k = ik_round_even(t);
                    k = (isnan(k) | isnan(fewest)) ? NAN : (k > fewest ? k : fewest);
                    k = (isnan(k) | isnan(most)) ? NAN : (k < most ? k : most);
                    if (fewest <= most && k != 0.0) m[j] = x[j] + k * IK_TWO_PI;
                }
                double diff = m[j] - r[j];
                sum = j == 0 ? diff * diff : sum + diff * diff;
            }
            key[b] = ik_sort_key(valid[i * K + b], sum);
        }
        for (npy_intp b = 0; b < K; ++b) { /* its place: the branches before it (stable) */
            npy_intp rank = 0;
            for (npy_intp c = 0; c < K; ++c) rank += (key[c] < key[b]) | ((key[c] == key[b]) & (c < b));
            order[rank] = b;
        }
        for (npy_intp b = 0; b < K; ++b) {
            memcpy(qo + (i * K + b) * J, moved + order[b] * J, sizeof(double) * (size_t)J);
            vo[i * K + b] = valid[i * K + order[b]];
        }
    }
    free(moved), free(key), free(order);
    return Py_BuildValue("(NN)", q_out, v_out);
}

/* rigid_targets(T) -> bool: True where T is exactly a C-contiguous, aligned, native float64
 * ndarray of shape (..., 4, 4) whose every matrix is a finite rigid transform by
 * poekin.ik.numerical.check_targets' tests (ik_rigid); False otherwise, the NumPy check then
 * deciding, and saying why. */
static PyObject *rigid_targets(PyObject *Py_UNUSED(mod), PyObject *obj) {
    PyArrayObject *a = ik_plain(obj);
    if (a == NULL) Py_RETURN_FALSE;
    int nd = PyArray_NDIM(a);
    const npy_intp *dims = PyArray_DIMS(a);
    if (nd < 2 || dims[nd - 2] != 4 || dims[nd - 1] != 4) Py_RETURN_FALSE;
    npy_intp count = PyArray_SIZE(a) / 16;
    const double *T = (const double *)PyArray_DATA(a);
    for (npy_intp t = 0; t < count; ++t)
        if (!ik_rigid(T + 16 * t)) Py_RETURN_FALSE;
    Py_RETURN_TRUE;
}

static PyMethodDef module_methods[] = {
    {"set_threads", set_threads, METH_O, "set_threads(n): threads for big batches"},
    {"get_threads", get_threads, METH_NOARGS, "get_threads() -> int"},
    {"set_width", set_width, METH_O, "set_width(n): 2, 4, 8 lanes, or 0 for the widest"},
    {"get_width", get_width, METH_NOARGS, "get_width() -> configurations per block"},
    {"ik_all", (PyCFunction)(void (*)(void))ik_all, METH_FASTCALL,
     "ik_all(kind, params, T, limits) -> (q, valid, bad): every closed-form IK branch"},
    {"quick_ik_all", (PyCFunction)(void (*)(void))quick_ik_all, METH_FASTCALL,
     "quick_ik_all(chain, T, near, kind, params, limits, geometry, result): Chain.ik_all's "
     "default call"},
    {"rigid_targets", rigid_targets, METH_O,
     "rigid_targets(T) -> bool: T a plain float64 (..., 4, 4) array of rigid transforms"},
    {"ordered", ordered, METH_VARARGS,
     "ordered(q, valid, ref, limits, revolute) -> (q, valid): branches nearest ref, sorted"},
    {"distance", distance, METH_VARARGS,
     "distance(kind1, T1, S1, kind2, T2, S2, options) -> (dist, points): gjk.distance's twin"},
    {"pair_distances", pair_distances, METH_VARARGS,
     "pair_distances(types, sizes, mesh_adr, mesh_num, mesh_vert, pairs, frames, frame_of, local, "
     "options, radii, cutoff, hit[, groups]) -> "
     "(dist, points), hit or first"},
    {"expose_python", expose_python, METH_VARARGS,
     "expose_python(get, call): FastMethod's __get__ and __call__ for tools that trace Python"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module_def = {
    PyModuleDef_HEAD_INIT, "poekin.kernel._kernel", "Compiled forward-kinematics kernel.", -1,
    module_methods, NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__kernel(void) {
    import_array();
    static const char *FORM_NAMES[3] = {"4x4", "3x4", "pos_quat"};
    for (int k = 0; k < 3; ++k)
        if ((g_form_names[k] = PyUnicode_InternFromString(FORM_NAMES[k])) == NULL) return NULL;
    if (PyType_Ready(&KernelType) < 0 || PyType_Ready(&FastMethodType) < 0 ||
        PyType_Ready(&IKSolverType) < 0)
        return NULL;
    PyObject *m = PyModule_Create(&module_def);
    if (m == NULL) return NULL;
    Py_INCREF(&KernelType);
    if (PyModule_AddObject(m, "Kernel", (PyObject *)&KernelType) < 0) {
        Py_DECREF(&KernelType);
        Py_DECREF(m);
        return NULL;
    }
    Py_INCREF(&IKSolverType);
    if (PyModule_AddObject(m, "IKSolver", (PyObject *)&IKSolverType) < 0) {
        Py_DECREF(&IKSolverType);
        Py_DECREF(m);
        return NULL;
    }
    Py_INCREF(&FastMethodType);
    if (PyModule_AddObject(m, "FastMethod", (PyObject *)&FastMethodType) < 0) {
        Py_DECREF(&FastMethodType);
        Py_DECREF(m);
        return NULL;
    }
    choose_width(0);
    return m;
}
