//! A cell's state between macro steps (opaque), and its bytes — preCICE's Micro
//! Manager's `get_state`/`set_state`: a flow solver that moves cells between ranks, or
//! checkpoints, keeps the bytes and makes the state again from them.

use agglo::subgrid::CellState;

use crate::error::{AggloStatus, Failure, guard, handle, out_pointer, slice};

/// A cell's state (opaque): made by the advance calls or `agglo_state_from_bytes`,
/// freed by `agglo_state_free`.
pub struct AggloCellState(pub(crate) CellState);

impl AggloCellState {
    pub(crate) fn into_raw(state: CellState) -> *mut Self {
        Box::into_raw(Box::new(Self(state)))
    }
}

/// The state's bytes: `*len` gets their number; when `bytes` is not NULL and `capacity`
/// is at least that, they are copied there (call once with NULL to size the buffer).
///
/// # Safety
/// `state` a live state; `bytes` NULL or `capacity` writable bytes; `len` writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn agglo_state_to_bytes(
    state: *const AggloCellState,
    bytes: *mut u8,
    capacity: usize,
    len: *mut usize,
) -> AggloStatus {
    guard(|| {
        out_pointer(len, "len")?;
        // SAFETY: the caller's contract.
        let encoded = unsafe { handle(state, "state") }?.0.to_bytes();
        // SAFETY: checked non-NULL.
        unsafe { *len = encoded.len() };
        if bytes.is_null() {
            return Ok(());
        }
        if capacity < encoded.len() {
            return Err(Failure::argument(format!(
                "capacity = {capacity} bytes for a state of {} bytes",
                encoded.len()
            )));
        }
        // SAFETY: `capacity` ≥ encoded.len() writable bytes.
        unsafe { std::ptr::copy_nonoverlapping(encoded.as_ptr(), bytes, encoded.len()) };
        Ok(())
    })
}

/// Make a state from `len` bytes given by `agglo_state_to_bytes`; `*out` gets it.
/// Bytes that are not a state are refused (`AGGLO_STATUS_STATE`).
///
/// # Safety
/// `bytes` points to `len` readable bytes; `out` writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn agglo_state_from_bytes(
    bytes: *const u8,
    len: usize,
    out: *mut *mut AggloCellState,
) -> AggloStatus {
    guard(|| {
        out_pointer(out, "out")?;
        // SAFETY: the caller's contract.
        let bytes = unsafe { slice(bytes, len, "bytes") }?;
        let state = CellState::from_bytes(bytes).map_err(|reason| Failure {
            status: AggloStatus::State,
            message: format!("state: {reason}"),
        })?;
        // SAFETY: checked non-NULL.
        unsafe { *out = AggloCellState::into_raw(state) };
        Ok(())
    })
}

/// Free a state (NULL is ignored).
///
/// # Safety
/// `state` is NULL or a state from this library not freed before.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn agglo_state_free(state: *mut AggloCellState) {
    if !state.is_null() {
        // SAFETY: made by Box::into_raw in this module, freed once (the caller's word).
        drop(unsafe { Box::from_raw(state) });
    }
}
