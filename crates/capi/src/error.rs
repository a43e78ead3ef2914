//! Result codes, the per-thread last error, and the guard every entry point runs in: a Rust
//! error becomes a code and a message, a panic becomes [`FurbakeResult::Internal`] and never
//! unwinds into the host.

use std::cell::RefCell;
use std::ffi::{CStr, CString, c_char};
use std::panic::{AssertUnwindSafe, catch_unwind};

use furbake_formats::FormatError;
use furbake_runtime::{RuntimeError, SceneError};

/// What a call did. Every failure also sets [`furbake_last_error`]'s message.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FurbakeResult {
    /// The call did what it says.
    Ok = 0,
    /// The caller's mistake: a null pointer, a descriptor whose `size` is too small, text that
    /// is not UTF-8, an index out of range, a matrix or value out of its allowed range.
    InvalidArgument = 1,
    /// The operating system could not give the file (missing, unreadable, not a regular file).
    Io = 2,
    /// The bytes are not a valid furbake pack (or a section of it is corrupt), or the pack is of
    /// a format version this library does not read.
    Format = 3,
    /// The pack holds no data of the kind asked for (no blade field in a fur pack, no skeleton
    /// in a static mesh, no topology the scene's effects can move).
    Missing = 4,
    /// The scene or effects text is invalid (the message names the key, what it expects and where).
    Scene = 5,
    /// The fur simulation refused its step or turned non-finite; the world should be released.
    Simulation = 6,
    /// The call came at the wrong time (a pack added to a world that has already stepped).
    State = 7,
    /// The header and the library disagree (`furbake_check_version`).
    Version = 8,
    /// A bug in furbake (a caught panic); the message says where. Please report it.
    Internal = 9,
}

/// A failed call: its code and message.
#[derive(Debug)]
pub(crate) struct Error {
    pub code: FurbakeResult,
    pub message: String,
}

impl Error {
    pub fn new(code: FurbakeResult, message: impl Into<String>) -> Error {
        Error { code, message: message.into() }
    }

    pub fn argument(message: impl Into<String>) -> Error {
        Error::new(FurbakeResult::InvalidArgument, message)
    }
}

fn format_code(e: &FormatError) -> FurbakeResult {
    match e {
        FormatError::Io { .. } => FurbakeResult::Io,
        FormatError::MissingSection { .. } => FurbakeResult::Missing,
        FormatError::Parameter { .. } => FurbakeResult::InvalidArgument,
        _ => FurbakeResult::Format,
    }
}

impl From<FormatError> for Error {
    fn from(e: FormatError) -> Error {
        Error::new(format_code(&e), e.to_string())
    }
}

impl From<RuntimeError> for Error {
    fn from(e: RuntimeError) -> Error {
        let code = match &e {
            RuntimeError::Format(f) => format_code(f),
            RuntimeError::Scene(SceneError::Io { .. }) => FurbakeResult::Io,
            RuntimeError::Scene(_) => FurbakeResult::Scene,
            RuntimeError::MissingTopology { .. } => FurbakeResult::Missing,
            RuntimeError::Simulation { .. } => FurbakeResult::Simulation,
            _ => FurbakeResult::InvalidArgument,
        };
        Error::new(code, e.to_string())
    }
}

thread_local! {
    static LAST_ERROR: RefCell<CString> = RefCell::new(CString::default());
}

/// `s` as a C string; a NUL inside it (a path or a glTF name could hold one) shows as U+FFFD
/// rather than cutting the text short.
pub(crate) fn c_string(s: &str) -> CString {
    CString::new(s.replace('\0', "\u{fffd}")).unwrap_or_default()
}

fn set_last_error(message: &str) {
    LAST_ERROR.with(|last| *last.borrow_mut() = c_string(message));
}

/// The message of the latest failed call on this thread, NUL-terminated UTF-8 (empty when no
/// call has failed yet). It names the file and the problem, e.g. `fox.fbk: the pack has no
/// blade field section`. Valid until the next failing call on the same thread; successful calls
/// leave it as it is.
#[unsafe(no_mangle)]
pub extern "C" fn furbake_last_error() -> *const c_char {
    LAST_ERROR.with(|last| last.borrow().as_ptr())
}

/// Runs one entry point's body: its error becomes the returned code and the thread's last
/// error; a panic is caught (it never unwinds into the host) and answered with
/// [`FurbakeResult::Internal`].
pub(crate) fn guard(body: impl FnOnce() -> Result<(), Error>) -> FurbakeResult {
    match catch_unwind(AssertUnwindSafe(body)) {
        Ok(Ok(())) => FurbakeResult::Ok,
        Ok(Err(e)) => {
            set_last_error(&e.message);
            e.code
        }
        Err(payload) => {
            let what = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "a panic without a message".into());
            set_last_error(&format!("internal error in furbake (please report it): {what}"));
            FurbakeResult::Internal
        }
    }
}

/// Reads a NUL-terminated UTF-8 argument.
pub(crate) fn text<'a>(what: &str, ptr: *const c_char) -> Result<&'a str, Error> {
    if ptr.is_null() {
        return Err(Error::argument(format!("{what} is a null pointer")));
    }
    // SAFETY: the caller passes a NUL-terminated string that lives for the call.
    unsafe { CStr::from_ptr(ptr) }.to_str().map_err(|e| Error::argument(format!("{what} is not UTF-8: {e}")))
}

/// Reads an optional NUL-terminated UTF-8 argument (null: none).
pub(crate) fn optional_text<'a>(what: &str, ptr: *const c_char) -> Result<Option<&'a str>, Error> {
    if ptr.is_null() { Ok(None) } else { text(what, ptr).map(Some) }
}

/// Borrows `count` elements at `ptr` (null is allowed when `count` is 0).
pub(crate) fn slice<'a, T>(what: &str, ptr: *const T, count: usize) -> Result<&'a [T], Error> {
    if count == 0 {
        return Ok(&[]);
    }
    if ptr.is_null() {
        return Err(Error::argument(format!("{what} is a null pointer with a count of {count}")));
    }
    if !(ptr as usize).is_multiple_of(std::mem::align_of::<T>()) {
        return Err(Error::argument(format!("{what} is not aligned to {} bytes", std::mem::align_of::<T>())));
    }
    // SAFETY: the caller passes `count` readable elements at `ptr` for the call's duration.
    Ok(unsafe { std::slice::from_raw_parts(ptr, count) })
}

/// Checks an output pointer.
pub(crate) fn out<'a, T>(what: &str, ptr: *mut T) -> Result<&'a mut T, Error> {
    // SAFETY: non-null pointers from the caller point to a writable `T`.
    unsafe { ptr.as_mut() }.ok_or_else(|| Error::argument(format!("{what} is a null pointer")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_panic_is_caught_and_reported_not_unwound() {
        let code = guard(|| panic!("the solver's index went astray"));
        assert_eq!(code, FurbakeResult::Internal);
        // SAFETY: the message is NUL-terminated and lives until the next failure.
        let message = unsafe { CStr::from_ptr(furbake_last_error()) }.to_str().unwrap().to_string();
        assert!(message.contains("internal error") && message.contains("the solver's index went astray"), "{message}");
        assert_eq!(guard(|| Ok(())), FurbakeResult::Ok);
        let error = guard(|| Err(Error::argument("x is a null pointer")));
        assert_eq!(error, FurbakeResult::InvalidArgument);
    }
}
