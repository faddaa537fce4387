"""Sparse direct solves: MKL PARDISO (pypardiso) when importable, SuperLU otherwise.

API
---
``factorize(A, backend=None, symmetric=True, matching=True, hermitian=False) -> Factor``
    ``Factor`` is callable: ``x = F(b)`` for ``b`` of shape (n,) or (n, k).
    ``F.backend`` names the backend that ran, ``F.seconds`` the factorisation time.
``backend_name(backend=None) -> "pardiso" | "superlu"``: what ``factorize`` would use.

Backends
--------
* ``"pardiso"``: real symmetric indefinite (``mtype=-2``, upper triangle passed with every
  diagonal entry stored, parallel METIS nested dissection returned in ``perm``, weighted
  matching + scaling for the saddle-point structure of the coupled piezo system);
  ``symmetric=False`` uses ``mtype=11``. pypardiso supports float64 only: a complex
  *symmetric* matrix ``A = Ar + j Ai`` is solved through the real symmetric equivalent
  ``[[Ar, Ai], [Ai, -Ar]] [xr; -xi] = [br; bi]`` (twice the size, still PARDISO).
  A complex *Hermitian* matrix (``hermitian=True``: a cyclic harmonic's reduced pencil) is
  factorised as it is (``mtype=-4``, through MKL's own entry point: pypardiso checks for float64
  only in its Python wrapper), about half the work and a third of the factor entries of its
  real equivalent ``[[Re A, -Im A], [Im A, Re A]]``.
* ``"superlu"``: ``scipy.sparse.linalg.splu`` with the COLAMD column ordering (scipy's
  default, a fill-reducing ordering); complex matrices are factorised as they are.

Reproducibility: MKL's threaded kernels may round differently from run to run (the order of
parallel sums changes), and the impact stage downstream is chaotic. Unless the user set it,
``MKL_CBWR=AUTO,STRICT`` (MKL conditional numerical reproducibility) is put into the environment
before MKL loads, so the same command on the same machine gives bit-identical factors.

Selection: ``backend`` argument, else the environment variable ``RPUD_SOLVER``
(``pardiso``/``superlu``), else PARDISO if pypardiso imports and finds MKL. Which one ran is
logged at INFO level.
"""

from __future__ import annotations

import ctypes
import glob
import logging
import os
import sys
import threading
import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from rpud_common import ParameterError, check_choice

__all__ = ["factorize", "backend_name", "Factor", "pardiso_available", "blas_threads"]

log = logging.getLogger(__name__)

# read by MKL when it initialises (first PARDISO call): bit-reproducible threaded results
os.environ.setdefault("MKL_CBWR", "AUTO,STRICT")

_PARDISO_OK: bool | None = None


def pardiso_available() -> bool:
    """True when pypardiso imports and MKL is found."""
    global _PARDISO_OK
    if _PARDISO_OK is None:
        try:
            if "PYPARDISO_MKL_RT" not in os.environ:
                # before the import: importing pypardiso makes a solver, whose own search runs
                # find_library and globs all of sys.prefix (~0.6 s); the mkl wheel puts MKL here
                for path in sorted(glob.glob(os.path.join(sys.prefix, "lib", "libmkl_rt.so*")), key=len):
                    try:
                        ctypes.CDLL(path)
                    except OSError:
                        continue
                    os.environ["PYPARDISO_MKL_RT"] = path
                    break
            import pypardiso

            solver = pypardiso.PyPardisoSolver()
            # MKL found elsewhere (find_library or pypardiso's search): remember it for the next solvers
            path = getattr(solver.libmkl, "_name", None)
            if path and "PYPARDISO_MKL_RT" not in os.environ:
                os.environ["PYPARDISO_MKL_RT"] = path
            _PARDISO_OK = True
        except Exception:  # ImportError, missing mkl_rt
            _PARDISO_OK = False
    return _PARDISO_OK


def backend_name(backend: str | None = None) -> str:
    """The backend :func:`factorize` will use for this argument/environment."""
    choice = backend or os.environ.get("RPUD_SOLVER") or "auto"
    check_choice("solver backend", choice, ("auto", "pardiso", "superlu"))
    if choice == "auto":
        return "pardiso" if pardiso_available() else "superlu"
    if choice == "pardiso" and not pardiso_available():
        raise ParameterError("solver backend", choice, "pypardiso/MKL is not available here")
    return choice


def blas_threads(n: int = 1, mkl: bool = False):
    """Limit the OpenBLAS threads (numpy's and scipy's bundled copies) inside a ``with`` block,
    and with ``mkl`` MKL's (PARDISO's) too.

    ARPACK's small dense updates gain nothing from threads, and OpenBLAS threads spinning next to
    PARDISO's MKL threads on 2 shared cores cost seconds per eigen solve. MKL keeps its threads
    unless ``mkl``: where several solves already run side by side (one per core), its threads only
    compete with them. Uses :class:`threadpoolctl.ThreadpoolController`. MKL's limit holds for
    the calling thread only (a thread started inside the block has MKL's default: limit it
    there), and only once MKL is loaded (:func:`pardiso_available` loads it).
    """
    from threadpoolctl import ThreadpoolController

    apis = ["openblas", "mkl"] if mkl else "openblas"
    return ThreadpoolController().select(internal_api=apis).limit(limits=int(n))


class Factor:
    """A factorised sparse matrix; call it with a right-hand side.

    Calls from several threads are safe: a factor's solves are taken one at a time (PARDISO's
    handle keeps its solve's work arrays, so two concurrent solves on one handle would share
    them; the pipeline's compliant stage solves with the harmonic basis's factor in its worker
    thread while the main thread may use the same basis).
    """

    backend: str
    seconds: float
    n: int

    def __call__(self, b: np.ndarray) -> np.ndarray:  # pragma: no cover - interface
        raise NotImplementedError


class _SuperLU(Factor):
    def __init__(self, A):
        self.backend = "superlu"
        self.n = A.shape[0]
        t = time.perf_counter()
        self.lu = spla.splu(sp.csc_matrix(A), permc_spec="COLAMD")
        self.seconds = time.perf_counter() - t
        self._lock = threading.Lock()

    def __call__(self, b):
        with self._lock:
            return self._solve(b)

    def _solve(self, b):
        b = np.asarray(b)
        if np.iscomplexobj(b) and not np.iscomplexobj(self.lu.L.data[:1]):
            return self.lu.solve(np.ascontiguousarray(b.real)) + 1j * self.lu.solve(np.ascontiguousarray(b.imag))
        if not np.iscomplexobj(b) and np.iscomplexobj(self.lu.L.data[:1]):
            b = b.astype(complex)
        return self.lu.solve(b)


class _Pardiso(Factor):
    def __init__(self, A, symmetric=True, matching=True, hermitian=False):
        self.backend = "pardiso(hermitian)" if hermitian else "pardiso"
        self.n = A.shape[0]
        self._lock = threading.Lock()
        self.symmetric = symmetric
        # complex Hermitian indefinite: half the factor entries of the real equivalent
        self.mtype = -4 if hermitian else (-2 if symmetric else 11)
        self.dtype = np.complex128 if hermitian else np.float64
        t = time.perf_counter()
        self.solver = self._new_solver()
        ip = self.solver.iparm
        ip[0] = 1      # user-supplied iparm
        ip[1] = 3      # METIS nested dissection, parallel (the same permutation here, ~0.3 s less)
        # return the ordering in perm: the same factors bit for bit, but MKL's factorisation
        # of the swept default mesh then takes 3.5 s instead of 4.3 s (free mesh 1.56 / 1.63 s;
        # measured, not documented by MKL)
        ip[4] = 2
        ip[9] = 8      # pivot perturbation 1e-8
        ip[10] = 1     # scaling
        ip[12] = 1 if matching else 0   # weighted matching (symmetric indefinite, saddle point)
        ip[17] = -1    # report nnz of the factor
        # Bunch-Kaufman 1x1 and 2x2 pivots in the Hermitian factorisation: with 1x1 pivots alone
        # (iparm all zero otherwise) a dense clustered Hermitian test pencil of condition 617 was
        # solved to a residual of 1.8e-9, with them to 7e-14 (measured)
        ip[20] = 1 if hermitian else 0
        A = sp.csr_matrix(A, dtype=self.dtype)
        if symmetric or hermitian:
            A = _upper(A)
        A.sort_indices()
        if not np.diff(A.indptr).all():
            raise ParameterError("matrix", "empty row", "matrix is singular (an empty row)")
        self.A = A
        if not hermitian:       # pypardiso's checks (those above) would convert a complex A to float64
            self.solver._check_A(A)
        # PARDISO's 1-based int32 index arrays, made once (pypardiso makes them on every call)
        self._ia = A.indptr.astype(np.int32) + 1
        self._ja = A.indices.astype(np.int32) + 1
        self._call(12, np.zeros((self.n, 1), dtype=self.dtype))
        self.perturbed = int(ip[13])
        if not matching and self.perturbed:
            # a pivot too small for Bunch-Kaufman within its supernode: redo with the matching
            log.info("PARDISO without matching perturbed %d pivots: factorising with it", self.perturbed)
            self._release()
            self.solver = self._new_solver(ip)
            self.solver.iparm[12] = 1
            self._call(12, np.zeros((self.n, 1), dtype=self.dtype))
            self.perturbed = int(self.solver.iparm[13])
        self.seconds = time.perf_counter() - t

    def _new_solver(self, iparm=None):
        """A pypardiso solver of this matrix type (``iparm`` copied if given) with an n-sized
        ``perm``, where PARDISO returns its ordering (``iparm[4] = 2``)."""
        import pypardiso

        solver = pypardiso.PyPardisoSolver(mtype=self.mtype)
        if iparm is not None:
            solver.iparm[:] = iparm
        solver.perm = np.zeros(self.n, dtype=np.int32)
        return solver

    def _release(self):
        """Free PARDISO's memory of the factorisation (phase -1)."""
        self.solver.set_phase(-1)
        self.solver._call_pardiso(sp.csr_matrix((0, 0)), np.zeros(0))

    def _call(self, phase, b):
        """One PARDISO call (``pypardiso.PyPardisoSolver._call_pardiso`` with the index arrays
        kept): ``b`` (n,) or (n, k) of the matrix's dtype, Fortran order; returns ``x`` in C
        order (the data pointers are passed as ``double *``: PARDISO reads complex ones as pairs)."""
        with self._lock:
            return self._call_locked(phase, b)

    def _call_locked(self, phase, b):
        s = self.solver
        x = np.zeros_like(b)
        err = ctypes.c_int32(0)
        i32, f64 = ctypes.POINTER(ctypes.c_int32), ctypes.POINTER(ctypes.c_double)
        s._mkl_pardiso(s.pt.ctypes.data_as(ctypes.POINTER(s._pt_type[0])), ctypes.byref(ctypes.c_int32(1)),
                       ctypes.byref(ctypes.c_int32(1)), ctypes.byref(ctypes.c_int32(s.mtype)),
                       ctypes.byref(ctypes.c_int32(phase)), ctypes.byref(ctypes.c_int32(self.n)),
                       self.A.data.ctypes.data_as(f64), self._ia.ctypes.data_as(i32), self._ja.ctypes.data_as(i32),
                       s.perm.ctypes.data_as(i32), ctypes.byref(ctypes.c_int32(1 if b.ndim == 1 else b.shape[1])),
                       s.iparm.ctypes.data_as(i32), ctypes.byref(ctypes.c_int32(s.msglvl)),
                       b.ctypes.data_as(f64), x.ctypes.data_as(f64), ctypes.byref(err))
        if err.value != 0:
            raise _pardiso_error(err.value)
        return np.ascontiguousarray(x)

    def _solve_real(self, b):
        return self._call(33, np.asfortranarray(b, dtype=np.float64))

    def __call__(self, b):
        b = np.asarray(b)
        if self.dtype is np.complex128:
            return self._call(33, np.asfortranarray(b, dtype=np.complex128))
        if np.iscomplexobj(b):
            return self._solve_real(b.real) + 1j * self._solve_real(b.imag)
        return self._solve_real(b)

    def __del__(self):
        try:
            self._release()
        except Exception:
            pass


def _pardiso_error(code: int) -> Exception:
    """pypardiso's exception for a PARDISO error code."""
    from pypardiso.pardiso_wrapper import PyPardisoError

    return PyPardisoError(code)


def _upper(A: sp.csr_matrix) -> sp.csr_matrix:
    """The upper triangle of a CSR matrix with sorted indices and every diagonal entry stored,
    as PARDISO's symmetric types require (an explicit 0 where the diagonal is empty; scipy's
    ``triu`` goes through COO: 3x slower on the article's drill)."""
    n = A.shape[0]
    A.sum_duplicates()          # sorted, one entry per position (as scipy's triu leaves it)
    rows = np.repeat(np.arange(n, dtype=A.indices.dtype), np.diff(A.indptr))
    keep = A.indices >= rows
    data, cols, rows = A.data[keep], A.indices[keep], rows[keep]
    empty = np.setdiff1d(np.arange(n), rows[cols == rows])
    if len(empty):
        # COO to CSR keeps explicit zeros (adding sp.diags(0) or setting 0 through LIL does not)
        up = sp.coo_matrix((np.concatenate([data, np.zeros(len(empty))]),
                            (np.concatenate([rows, empty]), np.concatenate([cols, empty]))), shape=A.shape).tocsr()
        up.sort_indices()
        return up
    indptr = np.concatenate([[0], np.cumsum(np.bincount(rows, minlength=n))])
    return sp.csr_matrix((data, cols, indptr), shape=A.shape)


class _ComplexViaReal(Factor):
    """Complex symmetric A = Ar + j Ai through the real symmetric [[Ar, Ai], [Ai, -Ar]]."""

    def __init__(self, A):
        Ar, Ai = sp.csr_matrix(A.real), sp.csr_matrix(A.imag)
        self.n = A.shape[0]
        self.inner = _Pardiso(sp.bmat([[Ar, Ai], [Ai, -Ar]], format="csr"), symmetric=True)
        self.backend = "pardiso(real-equivalent)"
        self.seconds = self.inner.seconds

    def __call__(self, b):
        b = np.asarray(b, dtype=complex)
        y = self.inner(np.concatenate([b.real, b.imag], axis=0))
        return y[: self.n] - 1j * y[self.n:]


def factorize(A, backend: str | None = None, symmetric: bool = True, matching: bool = True,
              hermitian: bool = False) -> Factor:
    """Factorise the square sparse matrix ``A`` (real, or complex symmetric, or complex Hermitian
    with ``hermitian=True``); see the module docstring for backends. ``symmetric`` tells PARDISO
    it may use only the upper triangle (``hermitian``: the upper triangle of a Hermitian ``A``).
    ``matching=False`` (real matrices, PARDISO): no weighted matching in the analysis, which
    saddle-point matrices with zero diagonal entries need but a matrix with a full non-zero
    diagonal (the shifted piezo pencil: stiffness minus mass, minus permittivity) does not
    (~20 % less factorisation work on the article's drill); if any pivot had to be perturbed the
    matrix is factorised again with the matching."""
    name = backend_name(backend)
    A = sp.csr_matrix(A)
    if A.shape[0] != A.shape[1]:
        raise ParameterError("matrix", A.shape, "must be square")
    if name == "pardiso":
        if hermitian:
            f = _Pardiso(A, matching=matching, hermitian=True)
        elif np.iscomplexobj(A.data):
            if not symmetric:
                log.info("complex unsymmetric matrix: SuperLU (pypardiso is real only)")
                f = _SuperLU(A)
            else:
                f = _ComplexViaReal(A)
        else:
            f = _Pardiso(A, symmetric=symmetric, matching=matching)
    else:
        f = _SuperLU(A)
    log.info("factorised n=%d nnz=%d with %s in %.2f s", A.shape[0], A.nnz, f.backend, f.seconds)
    return f
