//! Status codes, the last error's message per thread, and the guard every exported
//! function runs under, so that no panic unwinds into C.

use std::cell::RefCell;
use std::ffi::{CStr, CString, c_char};
use std::panic::{AssertUnwindSafe, catch_unwind};

use agglo::subgrid::SubgridError;

/// What a call did. Anything but `AGGLO_STATUS_OK` comes with a message from
/// `agglo_last_error()`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AggloStatus {
    /// Done.
    Ok = 0,
    /// A NULL pointer where a value is needed, a wrong length, text that is not UTF-8.
    Argument = 1,
    /// The scenario or the coupling's settings (edges, N, K) are unusable.
    Config = 2,
    /// A cell's input is out of range (the message names the cell and the field).
    Input = 3,
    /// A cell's state does not decode or belongs to another cell.
    State = 4,
    /// A box could not be set up or run, or the task farm failed.
    Run = 5,
    /// A bug inside the library (a caught panic); the message says where.
    Internal = 6,
}

/// A failed call: its status and message.
#[derive(Debug)]
pub(crate) struct Failure {
    pub status: AggloStatus,
    pub message: String,
}

impl Failure {
    pub fn argument(message: impl Into<String>) -> Self {
        Self {
            status: AggloStatus::Argument,
            message: message.into(),
        }
    }
}

impl From<SubgridError> for Failure {
    fn from(e: SubgridError) -> Self {
        Self {
            status: status_of(&e),
            message: e.to_string(),
        }
    }
}

/// The status a subgrid error maps to.
pub(crate) fn status_of(e: &SubgridError) -> AggloStatus {
    match e {
        SubgridError::Config { .. } => AggloStatus::Config,
        SubgridError::Input { .. } => AggloStatus::Input,
        SubgridError::State { .. } => AggloStatus::State,
        SubgridError::Run { .. } | SubgridError::Farm { .. } => AggloStatus::Run,
    }
}

thread_local! {
    static LAST_ERROR: RefCell<CString> = RefCell::new(CString::default());
}

fn set_last_error(message: &str) {
    // A message cannot hold NUL; none of ours do, but a scenario's text could.
    let text = CString::new(message.replace('\0', " ")).unwrap_or_default();
    LAST_ERROR.with(|e| *e.borrow_mut() = text);
}

/// The message of the last failed call on this thread ("" when the last call
/// succeeded). The pointer stays valid until the next agglo call on this thread; copy
/// the text to keep it.
#[unsafe(no_mangle)]
pub extern "C" fn agglo_last_error() -> *const c_char {
    LAST_ERROR.with(|e| e.borrow().as_ptr())
}

/// Run `body` as an exported call: its failure or panic becomes a status and the last
/// error's message; success clears the message.
pub(crate) fn guard(body: impl FnOnce() -> Result<(), Failure>) -> AggloStatus {
    // The handles a body touches are left as they were when it fails (outputs are
    // written last), so observing them after a caught panic is sound.
    match catch_unwind(AssertUnwindSafe(body)) {
        Ok(Ok(())) => {
            set_last_error("");
            AggloStatus::Ok
        }
        Ok(Err(failure)) => {
            set_last_error(&failure.message);
            failure.status
        }
        Err(payload) => {
            let what = agglo::farm::panic_message(payload.as_ref());
            set_last_error(&format!("internal error (a bug in agglo): {what}"));
            AggloStatus::Internal
        }
    }
}

/// The `len` values at `ptr` (`name` names the argument in the error).
///
/// # Safety
/// `ptr` is NULL or points to `len` readable values that outlive the call.
pub(crate) unsafe fn slice<'a, T>(
    ptr: *const T,
    len: usize,
    name: &str,
) -> Result<&'a [T], Failure> {
    if len == 0 {
        return Ok(&[]);
    }
    if ptr.is_null() {
        return Err(Failure::argument(format!(
            "{name} is NULL (it must point to {len} values)"
        )));
    }
    // SAFETY: the caller's contract.
    Ok(unsafe { std::slice::from_raw_parts(ptr, len) })
}

/// The text at `ptr`, which must be UTF-8 (`name` names the argument).
///
/// # Safety
/// `ptr` is NULL or points to a NUL-terminated string that outlives the call.
pub(crate) unsafe fn text<'a>(ptr: *const c_char, name: &str) -> Result<&'a str, Failure> {
    if ptr.is_null() {
        return Err(Failure::argument(format!("{name} is NULL")));
    }
    // SAFETY: the caller's contract.
    unsafe { CStr::from_ptr(ptr) }
        .to_str()
        .map_err(|e| Failure::argument(format!("{name} is not UTF-8 ({e})")))
}

/// The handle at `ptr` (`name` names the argument).
///
/// # Safety
/// `ptr` is NULL or a live handle of type `T` made by this library.
pub(crate) unsafe fn handle<'a, T>(ptr: *const T, name: &str) -> Result<&'a T, Failure> {
    // SAFETY: the caller's contract.
    unsafe { ptr.as_ref() }.ok_or_else(|| Failure::argument(format!("{name} is NULL")))
}

/// Check that an out-pointer is usable before any work is done.
pub(crate) fn out_pointer<T>(ptr: *mut T, name: &str) -> Result<(), Failure> {
    if ptr.is_null() {
        Err(Failure::argument(format!(
            "{name} is NULL (it must point to where the result goes)"
        )))
    } else {
        Ok(())
    }
}
