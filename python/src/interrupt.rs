//! A Ctrl-C that CPython would drop, raised again.
//!
//! CPython prints and then drops an exception raised inside a weakref callback or a `__del__`
//! ("Exception ignored in: ..."). importlib runs such callbacks during every import (its module
//! locks'), so a Ctrl-C landing in one while NumPy is imported, or later in any finaliser, was
//! lost and the run went on (CI, 2026-12: one child of sixteen in the start-up test). This
//! `sys.unraisablehook` keeps the interpreter's report (the previous hook) and then trips the
//! interrupt once more with `PyErr_SetInterrupt`. It is native code on purpose: a hook written
//! in Python would receive the new KeyboardInterrupt in its own frame, where it is dropped
//! again; from here no bytecode runs until the interrupted code resumes, which then raises it.

use pyo3::exceptions::PyKeyboardInterrupt;
use pyo3::prelude::*;
use pyo3::sync::GILOnceCell;
use pyo3::types::PyType;

/// `sys.unraisablehook` as it was before [`keep_dropped_interrupts`].
static PREVIOUS: GILOnceCell<PyObject> = GILOnceCell::new();

/// The hook: the previous one's report, then the interrupt raised again if it was one.
#[pyfunction]
fn unraisable_hook(py: Python<'_>, unraisable: &Bound<'_, PyAny>) -> PyResult<()> {
    if let Some(previous) = PREVIOUS.get(py) {
        previous.call1(py, (unraisable,))?;
    }
    let exc_type = unraisable.getattr("exc_type")?;
    if let Ok(t) = exc_type.downcast::<PyType>() {
        if t.is_subclass_of::<PyKeyboardInterrupt>()? {
            // SAFETY: called with the GIL held (`py`), as the C API requires.
            unsafe { pyo3::ffi::PyErr_SetInterrupt() };
        }
    }
    Ok(())
}

/// Installs the hook as `sys.unraisablehook`, once (a second call, as from a reload, keeps it).
#[pyfunction]
pub fn keep_dropped_interrupts(py: Python<'_>) -> PyResult<()> {
    if PREVIOUS.get(py).is_some() {
        return Ok(());
    }
    let sys = py.import("sys")?;
    // Under the GIL nothing else sets it between the check above and here.
    let _ = PREVIOUS.set(py, sys.getattr("unraisablehook")?.unbind());
    let hook = wrap_pyfunction!(unraisable_hook, py)?;
    sys.setattr("unraisablehook", hook)
}
