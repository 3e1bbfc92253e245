"""How starid compiles its kernels: two sets of numba flags, no more.

Every ``@njit`` kernel of the core and of the plugins is compiled with ``cache=True`` and
``no_cfunc_wrapper=True`` (no C entry point: nothing calls a kernel through ctypes or cffi, and the
entry point is compiled code on every cold cache): :data:`kernel`; a kernel that only other kernels
call also has ``no_cpython_wrapper=True`` (:data:`inner`); ``inline="always"`` on either is
:data:`inline_kernel` / :data:`inline_inner`. Kernels are decorated with these names rather than
spelling the flags out, so the set cannot drift from one file to the next. ptp's kernels add
``error_model="numpy"`` (its page says why). Why so few sets: numba compiles each numpy function a
kernel uses (``np.empty``, ``min``, ``np.argsort`` ...) once per set of flags of the kernels calling
it (its cache of implementations is keyed on the caller's flags), so every further set compiles them
again on a cold cache. Measured at stop 42: plain ``@njit(cache=True)`` kernels beside these two
sets cost about 4 % more cold-compile CPU for the fourteen plugins (``docs/performance.md``).
``tests/test_kernel_flags.py`` holds every kernel to this.
"""

from __future__ import annotations

from numba import njit

#: the flags of a kernel Python calls: cached, no C entry point
kernel = njit(cache=True, no_cfunc_wrapper=True)
#: the flags of a kernel that only other kernels call: no Python and no C entry point
inner = njit(cache=True, no_cpython_wrapper=True, no_cfunc_wrapper=True)
#: :data:`kernel` that numba also inlines at every call site (re-typed there: use where a profile asks)
inline_kernel = njit(cache=True, inline="always", no_cfunc_wrapper=True)
#: :data:`inner` that numba also inlines at every call site
inline_inner = njit(cache=True, inline="always", no_cpython_wrapper=True, no_cfunc_wrapper=True)
