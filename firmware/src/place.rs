//! Building a large value in place, field by field: [`place_fields!`].
//!
//! Rust has no placement construction. `slot.write(Firmware::blank(board))` builds the value on
//! the stack and then copies it, and the compiler removes the copy only when it can prove that
//! safe, which it does not here: written that way, the firmware's state (over 7 KB with a 6-joint
//! arm) took 7.9 KB of a board's start-up stack, whose whole budget is 8 KiB. So the few types that are that large
//! (the firmware, its core, the controller) have a `blank_at` that writes each field straight into
//! the destination, and their safe `blank` is built through it.

/// Writes every field of the struct behind the raw pointer `$at`: the plain ones with their value,
/// those `in place` by a function of the field's pointer (a nested `blank_at`).
///
/// Completeness is checked by the compiler: the same fields also form a struct literal (in a
/// branch that never runs), which does not compile if a field is missing. So once the macro has
/// run, the whole value is initialised.
///
/// Must be expanded inside `unsafe`, with `$at` valid for writes and aligned.
macro_rules! place_fields {
    (
        $at:ident: $ty:ident { $($field:ident: $value:expr),* $(,)? }
        $(in place { $($pfield:ident: $pvalue:expr => $place:expr),* $(,)? })?
    ) => {{
        #[allow(unreachable_code, clippy::diverging_sub_expression)]
        if false {
            let _every_field = $ty { $($field: $value,)* $($($pfield: $pvalue,)*)? };
        }
        $(core::ptr::addr_of_mut!((*$at).$field).write($value);)*
        $($(($place)(core::ptr::addr_of_mut!((*$at).$pfield));)*)?
    }};
}

pub(crate) use place_fields;
