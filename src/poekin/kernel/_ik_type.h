/*
 * Python type IKSolver(kernel, limits, flags, start_base, start_span): a chain's compiled
 * inverse kinematics solver (built by poekin.kernel._fast.ik_kernel). Included by _kernel.c after
 * the Kernel type, whose world-Jacobian program it runs.
 */

typedef struct {
    PyObject_HEAD PyObject *kernel; /* the KernelObject of the chain's world Jacobian */
    PyObject *args;                 /* the constructor's arguments, for pickling */
    IKModel model;
    double *numbers; /* lo, hi, base, span: n each (owned) */
    int *flags;      /* owned */
    PyObject *options; /* the options tuple of the last solve, read into opt (a reference) */
    IKOptions opt;
} IKSolverObject;

static void IKSolver_dealloc(IKSolverObject *self) {
    Py_XDECREF(self->options);
    Py_XDECREF(self->kernel);
    Py_XDECREF(self->args);
    PyMem_Free(self->numbers);
    PyMem_Free(self->flags);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static PyObject *IKSolver_reduce(IKSolverObject *self, PyObject *Py_UNUSED(ignored)) {
    return Py_BuildValue("OO", Py_TYPE(self), self->args);
}

/* A float64 array of n rows of `cols` numbers, or NULL with an exception set. */
static PyArrayObject *ik_array(PyObject *obj, int type, npy_intp n, int cols, const char *name) {
    PyArrayObject *a = (PyArrayObject *)PyArray_FROMANY(obj, type, cols ? 2 : 1, cols ? 2 : 1,
                                                        NPY_ARRAY_CARRAY);
    if (a == NULL) return NULL;
    if (PyArray_DIM(a, 0) != n || (cols && PyArray_DIM(a, 1) != cols)) {
        PyErr_Format(PyExc_ValueError, "%s has the wrong shape", name);
        Py_DECREF(a);
        return NULL;
    }
    return a;
}

static int IKSolver_init(IKSolverObject *self, PyObject *args, PyObject *kwds) {
    static char *kwlist[] = {"kernel", "limits", "flags", "start_base", "start_span", NULL};
    PyObject *kernel, *limits, *flags, *base, *span;
    if (!PyArg_ParseTupleAndKeywords(args, kwds, "O!OOOO", kwlist, &KernelType, &kernel, &limits,
                                     &flags, &base, &span))
        return -1;
    const Program *prog = &((KernelObject *)kernel)->prog;
    const int n = prog->jac_cols;
    if (n < 1 || n > IK_MAX_JOINTS || prog->nq != n) {
        PyErr_Format(PyExc_ValueError, "IKSolver needs a chain's Jacobian program of 1 to %d joints",
                     IK_MAX_JOINTS);
        return -1;
    }
    PyArrayObject *a[4] = {ik_array(limits, NPY_FLOAT64, n, 2, "limits"),
                           ik_array(flags, NPY_INT32, n, 0, "flags"),
                           ik_array(base, NPY_FLOAT64, n, 0, "start_base"),
                           ik_array(span, NPY_FLOAT64, n, 0, "start_span")};
    double *numbers = PyMem_Malloc(sizeof(double) * 4 * n);
    int *fl = PyMem_Malloc(sizeof(int) * n);
    int ok = a[0] && a[1] && a[2] && a[3] && numbers && fl;
    if (ok) {
        const double *lim = PyArray_DATA(a[0]);
        for (int j = 0; j < n; ++j) {
            numbers[j] = lim[2 * j];
            numbers[n + j] = lim[2 * j + 1];
            numbers[2 * n + j] = ((const double *)PyArray_DATA(a[2]))[j];
            numbers[3 * n + j] = ((const double *)PyArray_DATA(a[3]))[j];
            fl[j] = ((const int32_t *)PyArray_DATA(a[1]))[j];
        }
    }
    for (int k = 0; k < 4; ++k) Py_XDECREF(a[k]);
    if (!ok) {
        PyMem_Free(numbers);
        PyMem_Free(fl);
        if (!PyErr_Occurred()) PyErr_NoMemory();
        return -1;
    }
    PyMem_Free(self->numbers);
    PyMem_Free(self->flags);
    self->numbers = numbers;
    self->flags = fl;
    Py_INCREF(kernel);
    Py_XSETREF(self->kernel, kernel);
    Py_INCREF(args);
    Py_XSETREF(self->args, args);
    self->model = (IKModel){prog, n, numbers, numbers + n, numbers + 2 * n, numbers + 3 * n, fl};
    return 0;
}

/* Whether the 4x4 T is finite and rigid, by poekin.ik.numerical.check_targets' tests. */
static int ik_rigid(const double *T) {
    for (int k = 0; k < 16; ++k)
        if (!isfinite(T[k])) return 0;
    if (fabs(T[12]) > 1e-12 || fabs(T[13]) > 1e-12 || fabs(T[14]) > 1e-12 || fabs(T[15] - 1.0) > 1e-12)
        return 0;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
            double g = T[i] * T[j] + T[4 + i] * T[4 + j] + T[8 + i] * T[8 + j];
            if (fabs(g - (i == j ? 1.0 : 0.0)) > 1e-6) return 0;
        }
    double det = T[0] * (T[5] * T[10] - T[6] * T[9]) - T[1] * (T[4] * T[10] - T[6] * T[8]) +
                 T[2] * (T[4] * T[9] - T[5] * T[8]);
    return det > 0;
}

/* A C-contiguous, aligned, native float64 ndarray (exactly), else NULL. */
static PyArrayObject *ik_plain(PyObject *obj) {
    if (!PyArray_CheckExact(obj)) return NULL;
    PyArrayObject *a = (PyArrayObject *)obj;
    if (PyArray_TYPE(a) != NPY_FLOAT64 || !PyArray_IS_C_CONTIGUOUS(a) || !PyArray_ISALIGNED(a) ||
        PyArray_ISBYTESWAPPED(a))
        return NULL;
    return a;
}

static int ik_read_options(PyObject *obj, IKOptions *o) {
    if (!PyTuple_Check(obj) || PyTuple_GET_SIZE(obj) != IK_N_OPTIONS) {
        PyErr_SetString(PyExc_TypeError, "options must be a tuple of 14 numbers");
        return -1;
    }
    double x[IK_N_OPTIONS];
    for (int k = 0; k < IK_N_OPTIONS; ++k) {
        x[k] = PyFloat_AsDouble(PyTuple_GET_ITEM(obj, k));
        if (x[k] == -1.0 && PyErr_Occurred()) return -1;
    }
    *o = (IKOptions){x[0], x[1], x[2], x[3], x[4], x[5], x[6], x[7], x[8], x[9],
                     (int)x[10], (int)x[11], (int)x[12], (int)x[13]};
    return 0;
}

#ifdef _WIN32
static DWORD WINAPI ik_thread_main(LPVOID arg) {
    g_ik_run_task((IKTask *)arg);
    return 0;
}
#else
static void *ik_thread_main(void *arg) {
    g_ik_run_task((IKTask *)arg);
    return NULL;
}
#endif

/* Run the solve on up to `threads` threads, which take targets from one shared counter. */
static int ik_run(IKTask *proto, int threads) {
    IKTask tasks[MAX_THREADS];
    npy_intp next = 0;
    npy_intp most = proto->N / IK_MIN_TARGETS_PER_THREAD;
    int nt = threads < most ? threads : (int)(most > 0 ? most : 1);
    if (nt > MAX_THREADS) nt = MAX_THREADS;
#ifdef _WIN32
    HANDLE handles[MAX_THREADS];
#else
    pthread_t handles[MAX_THREADS];
#endif
    int started[MAX_THREADS];
    /* fewer targets than lanes: a target's attempts side by side, on G lanes each, G at most
     * the attempts there are (every lane of a group runs at least one) */
    int lanes = g_lanes;
    IKTaskFn run_task = g_ik_run_task;
#ifdef X86_DISPATCH
    /* a few targets (one thread) on AVX2's 4 lanes rather than AVX-512's 8: an iteration costs
     * less there and the attempts past the first 4 are rarely needed (every width gives the
     * same bits) */
    if (proto->N <= 4 && lanes == 8) {
        lanes = 4;
        run_task = ik_run_task_4;
    }
#endif
    int group = 1;
    while (2 * group * proto->N <= lanes && 2 * group <= proto->opt->max_attempts) group *= 2;
    for (int k = 0; k < nt; ++k) {
        tasks[k] = *proto;
        tasks[k].next = &next;
        tasks[k].group = group;
    }
    for (int k = 1; k < nt; ++k) {
#ifdef _WIN32
        handles[k] = CreateThread(NULL, 0, ik_thread_main, &tasks[k], 0, NULL);
        started[k] = handles[k] != NULL;
#else
        started[k] = pthread_create(&handles[k], NULL, ik_thread_main, &tasks[k]) == 0;
#endif
    }
    run_task(&tasks[0]); /* the others, if any (nt > 1: many targets), at g_lanes */
    for (int k = 1; k < nt; ++k) {
        if (!started[k]) continue; /* the others took its targets */
#ifdef _WIN32
        WaitForSingleObject(handles[k], INFINITE);
        CloseHandle(handles[k]);
#else
        pthread_join(handles[k], NULL);
#endif
    }
    /* a thread finishes every target it takes; one without memory takes none */
    return next < proto->N ? -1 : 0;
}

/* An instance of the class `type` (a frozen dataclass: poekin.ik.numerical.IKResult,
 * poekin.ik.analytic.IKSolutions) with the n values as its attributes `names` (interned
 * strings), as object.__new__ and the dataclass's own __init__ would set them; NULL with an
 * exception set. Steals the n references. */
static PyObject *ik_new_result(PyObject *type, PyObject *const *names, PyObject **values, int n) {
    PyObject *obj = NULL, *empty = NULL;
    if (!PyType_Check(type)) {
        PyErr_SetString(PyExc_TypeError, "a result type must be a class");
        goto done;
    }
    empty = PyTuple_New(0);
    if (empty == NULL) goto done;
    obj = PyBaseObject_Type.tp_new((PyTypeObject *)type, empty, NULL);
    for (int k = 0; k < n && obj != NULL; ++k)
        if (PyObject_GenericSetAttr(obj, names[k], values[k]) < 0) Py_CLEAR(obj);
done:
    Py_XDECREF(empty);
    for (int k = 0; k < n; ++k) Py_DECREF(values[k]);
    return obj;
}

/* interned[k], the n C strings of names interned where not yet; -1 with an exception set. */
static int ik_intern(const char *const *names, PyObject **interned, int n) {
    for (int k = 0; k < n; ++k)
        if (interned[k] == NULL && (interned[k] = PyUnicode_InternFromString(names[k])) == NULL)
            return -1;
    return 0;
}

/* An IK result (poekin.ik.numerical.IKResult) of the six arrays of solve, in its order. */
static PyObject *ik_result(PyObject *type, PyObject *out[6]) {
    static const char *names[6] = {"q", "success", "pos_err", "ori_err", "iterations", "attempts"};
    static PyObject *interned[6];
    if (ik_intern(names, interned, 6) < 0) {
        for (int k = 0; k < 6; ++k) Py_DECREF(out[k]);
        return NULL;
    }
    return ik_new_result(type, interned, out, 6);
}

/* solve(T, q0, seed, options, checked[, result]): (q, success, pos_err, ori_err, iterations,
 * attempts) for (..., 4, 4) targets T and (..., n) starts q0 of the same batch shape (or None),
 * or, given the class `result`, an instance of it with those six attributes; None if the
 * arguments need validating first (not plain float64 arrays of those shapes, or, unless
 * checked, targets that are not finite rigid transforms or starts that are not finite and
 * within the limits). */
static PyObject *IKSolver_solve(IKSolverObject *self, PyObject *const *args, Py_ssize_t nargs) {
    if (nargs != 5 && nargs != 6) {
        PyErr_SetString(PyExc_TypeError, "solve(T, q0, seed, options, checked[, result])");
        return NULL;
    }
    const IKModel *m = &self->model;
    IKOptions opt;
    if (args[3] == self->options && self->options != NULL) {
        opt = self->opt; /* the same tuple as the last solve's: its numbers, read then */
    } else {
        if (ik_read_options(args[3], &opt) < 0) return NULL;
        Py_XSETREF(self->options, Py_NewRef(args[3]));
        self->opt = opt;
    }
    uint64_t seed = PyLong_AsUnsignedLongLong(args[2]);
    if (seed == (uint64_t)-1 && PyErr_Occurred()) return NULL;
    int checked = PyObject_IsTrue(args[4]);
    if (checked < 0) return NULL;
    PyArrayObject *T = ik_plain(args[0]);
    if (T == NULL) Py_RETURN_NONE;
    const int nd = PyArray_NDIM(T);
    if (nd < 2 || PyArray_DIM(T, nd - 1) != 4 || PyArray_DIM(T, nd - 2) != 4)
        Py_RETURN_NONE;
    npy_intp dims[NPY_MAXDIMS];
    npy_intp N = 1;
    for (int i = 0; i < nd - 2; ++i) {
        dims[i] = PyArray_DIM(T, i);
        N *= dims[i];
    }
    dims[nd - 2] = m->n;
    PyArrayObject *q0 = NULL;
    if (args[1] != Py_None) {
        q0 = ik_plain(args[1]);
        if (q0 == NULL || PyArray_NDIM(q0) != nd - 1 ||
            !PyArray_CompareLists(PyArray_DIMS(q0), dims, nd - 1))
            Py_RETURN_NONE;
    }
    const double *Td = PyArray_DATA(T);
    const double *q0d = q0 != NULL ? PyArray_DATA(q0) : NULL;
    if (!checked) {
        for (npy_intp t = 0; t < N; ++t)
            if (!ik_rigid(Td + 16 * t)) Py_RETURN_NONE;
        /* a start outside the limits gets poekin.JointLimitsWarning from the Python side */
        for (npy_intp k = 0; q0d != NULL && k < N * m->n; ++k)
            if (!isfinite(q0d[k]) || q0d[k] < m->lo[k % m->n] || q0d[k] > m->hi[k % m->n])
                Py_RETURN_NONE;
    }
    PyObject *out[6] = {
        PyArray_SimpleNew(nd - 1, dims, NPY_FLOAT64), PyArray_SimpleNew(nd - 2, dims, NPY_BOOL),
        PyArray_SimpleNew(nd - 2, dims, NPY_FLOAT64), PyArray_SimpleNew(nd - 2, dims, NPY_FLOAT64),
        PyArray_SimpleNew(nd - 2, dims, NPY_INT64),   PyArray_SimpleNew(nd - 2, dims, NPY_INT64)};
    for (int k = 0; k < 6; ++k)
        if (out[k] == NULL) {
            for (int i = 0; i < 6; ++i) Py_XDECREF(out[i]);
            return NULL;
        }
    IKTask task = {m,
                   &opt,
                   seed,
                   Td,
                   q0d,
                   N,
                   NULL,
                   1,
                   PyArray_DATA((PyArrayObject *)out[0]),
                   PyArray_DATA((PyArrayObject *)out[1]),
                   PyArray_DATA((PyArrayObject *)out[2]),
                   PyArray_DATA((PyArrayObject *)out[3]),
                   PyArray_DATA((PyArrayObject *)out[4]),
                   PyArray_DATA((PyArrayObject *)out[5]),
                   0};
    int status = 0;
    if (N > 0) {
        int threads = g_threads;
        Py_BEGIN_ALLOW_THREADS status = ik_run(&task, threads);
        Py_END_ALLOW_THREADS
    }
    if (status != 0) {
        for (int i = 0; i < 6; ++i) Py_DECREF(out[i]);
        return PyErr_NoMemory();
    }
    if (nargs == 6) return ik_result(args[5], out);
    PyObject *result = PyTuple_New(6);
    if (result == NULL) {
        for (int i = 0; i < 6; ++i) Py_DECREF(out[i]);
        return NULL;
    }
    for (int k = 0; k < 6; ++k) PyTuple_SET_ITEM(result, k, out[k]);
    return result;
}

/* One thread's share of a step's batch (IKSolver_step). */
typedef struct {
    IKStepFn fn;
    const IKModel *m;
    const IKOptions *o;
    const double *T, *q, *reach;
    double gain, lam, release;
    int rounds;
    npy_intp first, last;
    double *x;
    int status;
} IKStepShare;

static void ik_step_share(void *arg) {
    IKStepShare *a = arg;
    a->status = a->fn(a->m, a->o, a->T, a->q, a->reach, a->gain, a->lam, a->release, a->rounds,
                      a->first, a->last, a->x);
}

/* Steps per thread below which another thread does not pay for its start (about 0.15 ms). */
#define IK_STEP_MIN_PER_THREAD 256

/* step(T, q, reach, options, gain, lam, release, rounds, checked) -> x: poekin.ik.step's step
 * (the bounds from the limits and each joint's reach, v dt) for (..., 4, 4) targets and (..., n)
 * q of one batch shape, plain float64 arrays, and (n,) reach; None if the arguments need
 * validating first (not such arrays, or, unless checked, targets that are not finite rigid
 * transforms or q that is not finite), or if the chain has more joints than the twin takes. One
 * thread: a control tick's batch is small work. */
static PyObject *IKSolver_step(IKSolverObject *self, PyObject *const *args, Py_ssize_t nargs) {
    if (nargs != 9) {
        PyErr_SetString(PyExc_TypeError,
                        "step(T, q, reach, options, gain, lam, release, rounds, checked)");
        return NULL;
    }
    const IKModel *m = &self->model;
    const int n = m->n;
    if (n > IK_STEP_MAX_JOINTS) Py_RETURN_NONE;
    IKOptions opt;
    if (ik_read_options(args[3], &opt) < 0) return NULL;
    const double gain = PyFloat_AsDouble(args[4]), lam = PyFloat_AsDouble(args[5]),
                 release = PyFloat_AsDouble(args[6]);
    const long rounds = PyLong_AsLong(args[7]);
    const int checked = PyObject_IsTrue(args[8]);
    if (PyErr_Occurred() || checked < 0) return NULL;
    PyArrayObject *T = ik_plain(args[0]), *q = ik_plain(args[1]), *reach = ik_plain(args[2]);
    if (T == NULL || q == NULL || reach == NULL) Py_RETURN_NONE;
    const int nd = PyArray_NDIM(T);
    if (nd < 2 || PyArray_DIM(T, nd - 1) != 4 || PyArray_DIM(T, nd - 2) != 4) Py_RETURN_NONE;
    if (PyArray_NDIM(reach) != 1 || PyArray_DIM(reach, 0) != n) Py_RETURN_NONE;
    npy_intp dims[NPY_MAXDIMS], N = 1;
    for (int i = 0; i < nd - 2; ++i) {
        dims[i] = PyArray_DIM(T, i);
        N *= dims[i];
    }
    dims[nd - 2] = n;
    if (PyArray_NDIM(q) != nd - 1 || !PyArray_CompareLists(PyArray_DIMS(q), dims, nd - 1))
        Py_RETURN_NONE;
    const double *Td = PyArray_DATA(T), *qd = PyArray_DATA(q), *rd = PyArray_DATA(reach);
    if (!checked) {
        for (npy_intp t = 0; t < N; ++t)
            if (!ik_rigid(Td + 16 * t)) Py_RETURN_NONE;
        for (npy_intp k = 0; k < N * n; ++k)
            if (!isfinite(qd[k])) Py_RETURN_NONE;
    }
    PyObject *out = PyArray_SimpleNew(nd - 1, dims, NPY_FLOAT64);
    if (out == NULL) return NULL;
    int status = 0;
    if (N > 0) {
        /* a few steps on the narrowest width that holds them: a block costs about the same
         * whatever it holds (every width gives the same bits) */
        IKStepFn fn = g_ik_step_task;
#ifdef X86_DISPATCH
        if (N <= 4 && g_lanes >= 4) fn = ik_step_task_4;
#endif
        IKStepShare tasks[MAX_THREADS];
        Share shares[MAX_THREADS];
        npy_intp chunk;
        const int nt = split_batch(N, IK_STEP_MIN_PER_THREAD, g_threads, &chunk);
        for (int k = 0; k < nt; ++k) {
            const npy_intp first = k * chunk < N ? k * chunk : N;
            tasks[k] = (IKStepShare){fn, m, &opt, Td, qd, rd, gain, lam, release, (int)rounds,
                                     first, first + chunk < N ? first + chunk : N,
                                     PyArray_DATA((PyArrayObject *)out), 0};
            shares[k] = (Share){ik_step_share, &tasks[k]};
        }
        Py_BEGIN_ALLOW_THREADS run_shares(shares, nt);
        Py_END_ALLOW_THREADS
        for (int k = 0; k < nt; ++k) status |= tasks[k].status;
    }
    if (status != 0) {
        Py_DECREF(out);
        return PyErr_NoMemory();
    }
    return out;
}

/* The seed 0 (Chain.ik's default), made once. */
static PyObject *ik_seed_zero;

/* quick(chain, T, q0, options, result): Chain.ik(T[, q0]) with every other argument at its
 * default, as poekin.ik.numerical arms it (the chain's _ik_quick, which FastMethod calls):
 * solve(T, q0, 0, options, False, result), None where that needs the usual path (issue 26: a
 * single call's own cost, without a Python frame). */
static PyObject *IKSolver_quick(IKSolverObject *self, PyObject *const *args, Py_ssize_t nargs) {
    if (nargs != 5) {
        PyErr_SetString(PyExc_TypeError, "quick(chain, T, q0, options, result)");
        return NULL;
    }
    if (ik_seed_zero == NULL && (ik_seed_zero = PyLong_FromLong(0)) == NULL) return NULL;
    PyObject *solve_args[6] = {args[1], args[2], ik_seed_zero, args[3], Py_False, args[4]};
    return IKSolver_solve(self, solve_args, 6);
}

static PyMethodDef IKSolver_methods[] = {
    {"solve", (PyCFunction)(void (*)(void))IKSolver_solve, METH_FASTCALL,
     "solve(T, q0, seed, options, checked) -> (q, success, pos_err, ori_err, iterations, "
     "attempts), or None if the arguments need validating first"},
    {"step", (PyCFunction)(void (*)(void))IKSolver_step, METH_FASTCALL,
     "step(T, q, reach, options, gain, lam, release, rounds, checked) -> x, the differential "
     "step of poekin.ik.step, or None if the arguments need validating first"},
    {"quick", (PyCFunction)(void (*)(void))IKSolver_quick, METH_FASTCALL,
     "quick(chain, T, q0, options, result): Chain.ik's call with the other arguments at their "
     "defaults, solve(T, q0, 0, options, False, result)"},
    {"__reduce__", (PyCFunction)IKSolver_reduce, METH_NOARGS, NULL},
    {NULL, NULL, 0, NULL},
};

static PyTypeObject IKSolverType = {
    PyVarObject_HEAD_INIT(NULL, 0).tp_name = "poekin.kernel._kernel.IKSolver",
    .tp_basicsize = sizeof(IKSolverObject),
    .tp_dealloc = (destructor)IKSolver_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "A chain's compiled inverse kinematics solver (built by poekin.kernel._fast.ik_kernel).",
    .tp_methods = IKSolver_methods,
    .tp_init = (initproc)IKSolver_init,
    .tp_new = PyType_GenericNew,
};
