//! The one guard around `geo`'s boolean operations on a building's footprint (union, the
//! re-noding of a crossing ring). They run i_overlay, which can panic on pathological input:
//! a debug assertion (`extract_ogc.rs`, "overlay_rule.is_fill_top(link.fill)") and an index out
//! of bounds were found by fuzzing (iShape-Rust/iOverlay#78, #79; `tests/fuzz/README.md`). Such
//! a panic rejects the one building, with its reason, and the load goes on.

use std::panic::{AssertUnwindSafe, catch_unwind};

use crate::report::RejectReason;

/// Runs `op`, an overlay of one footprint; a panic inside it becomes the building's rejection,
/// naming `what` failed and the panic's message.
pub(crate) fn overlay_or_reject<T>(what: &str, op: impl FnOnce() -> T) -> Result<T, RejectReason> {
    catch_unwind(AssertUnwindSafe(op)).map_err(|panic| {
        let why = panic_message(panic.as_ref());
        RejectReason::InvalidGeometry(format!("{what} failed inside i_overlay: {why}"))
    })
}

/// The message a caught panic carries (`panic!`'s text), or "no message".
pub fn panic_message(panic: &(dyn std::any::Any + Send)) -> String {
    panic
        .downcast_ref::<&str>()
        .map(|s| (*s).to_owned())
        .or_else(|| panic.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "no message".to_owned())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_panic_becomes_a_rejection_naming_the_operation_and_its_message() {
        assert_eq!(overlay_or_reject("the union", || 7), Ok(7));
        let rejected = overlay_or_reject("the union", || -> u32 { panic!("index out of bounds") });
        assert_eq!(
            rejected,
            Err(RejectReason::InvalidGeometry(
                "the union failed inside i_overlay: index out of bounds".into()
            ))
        );
        let formatted = overlay_or_reject("the re-noding", || -> u32 { panic!("at {}", 3) });
        assert_eq!(
            formatted,
            Err(RejectReason::InvalidGeometry(
                "the re-noding failed inside i_overlay: at 3".into()
            ))
        );
    }
}
