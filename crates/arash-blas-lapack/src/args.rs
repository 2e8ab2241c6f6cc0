//! Reading Fortran-style arguments: option letters, dimensions, and column-major views of the
//! caller's arrays.

use core::ffi::{c_char, c_int};
use core::ops::{Add, AddAssign, Div, Mul, Neg, Sub};

use faer::{MatMut, MatRef};

/// The two precisions BLAS and LAPACK come in.
pub trait Real:
    faer::traits::RealField
    + Copy
    + PartialOrd
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
{
    const ZERO: Self;
    const ONE: Self;
    fn from_usize(n: usize) -> Self;
}

impl Real for f64 {
    const ZERO: Self = 0.0;
    const ONE: Self = 1.0;
    fn from_usize(n: usize) -> Self {
        n as f64
    }
}

impl Real for f32 {
    const ZERO: Self = 0.0;
    const ONE: Self = 1.0;
    fn from_usize(n: usize) -> Self {
        n as f32
    }
}

/// An option letter (`'N'`, `'U'`, ...), upper-cased as LAPACK's `LSAME` compares them.
///
/// # Safety
/// `c` points to a readable byte.
pub unsafe fn letter(c: *const c_char) -> u8 {
    (*c as u8).to_ascii_uppercase()
}

/// A dimension, increment or leading dimension.
///
/// # Safety
/// `n` points to a readable integer.
pub unsafe fn int(n: *const c_int) -> i64 {
    i64::from(*n)
}

/// Whether an operand is used transposed (`'T'` or `'C'`, the same for real data), or `None` for
/// a letter that is neither that nor `'N'`.
pub fn transposed(trans: u8) -> Option<bool> {
    match trans {
        b'N' => Some(false),
        b'T' | b'C' => Some(true),
        _ => None,
    }
}

/// Whether the upper triangle is the one referenced (`'U'`), or `None` for a letter that is
/// neither `'U'` nor `'L'`.
pub fn upper(uplo: u8) -> Option<bool> {
    match uplo {
        b'U' => Some(true),
        b'L' => Some(false),
        _ => None,
    }
}

/// The first argument (1-based, as BLAS numbers them) whose check fails, or 0.
pub fn first_bad(checks: &[(bool, i32)]) -> i32 {
    checks.iter().find(|(ok, _)| !ok).map_or(0, |&(_, position)| position)
}

/// A reference BLAS routine stops the program on a bad argument (`XERBLA`); so does this one,
/// naming the argument, since the routines without `INFO` have no other way to say it.
pub fn xerbla(routine: &str, position: i32) {
    if position != 0 {
        panic!("{routine}: argument {position} is invalid (BLAS XERBLA)");
    }
}

/// The `rows × cols` column-major matrix at `a` with leading dimension `ld`.
///
/// # Safety
/// `a` holds `ld · (cols − 1) + rows` readable elements (when neither is zero), and `ld ≥ rows`.
pub unsafe fn view<'a, T>(a: *const T, rows: i64, cols: i64, ld: i64) -> MatRef<'a, T> {
    let a = if rows == 0 || cols == 0 { core::ptr::NonNull::<T>::dangling().as_ptr() } else { a.cast_mut() };
    MatRef::from_raw_parts(a, rows as usize, cols as usize, 1, ld as isize)
}

/// The mutable counterpart of [`view`].
///
/// # Safety
/// As for [`view`], with the elements writable and not otherwise borrowed.
pub unsafe fn view_mut<'a, T>(a: *mut T, rows: i64, cols: i64, ld: i64) -> MatMut<'a, T> {
    let a = if rows == 0 || cols == 0 { core::ptr::NonNull::<T>::dangling().as_ptr() } else { a };
    MatMut::from_raw_parts_mut(a, rows as usize, cols as usize, 1, ld as isize)
}

/// The `len` elements of the BLAS vector at `x` with increment `inc` (≠ 0), as a column: a
/// negative increment walks the array backwards from its far end, as BLAS defines it.
///
/// # Safety
/// `x` holds `|inc| · (len − 1) + 1` readable elements when `len > 0`.
pub unsafe fn vector<'a, T>(x: *const T, len: i64, inc: i64) -> MatRef<'a, T> {
    let start = if inc < 0 && len > 0 { x.offset(((len - 1) * -inc) as isize) } else { x };
    let start = if len == 0 { core::ptr::NonNull::<T>::dangling().as_ptr() } else { start.cast_mut() };
    MatRef::from_raw_parts(start, len as usize, 1, inc as isize, 0)
}

/// The mutable counterpart of [`vector`].
///
/// # Safety
/// As for [`vector`], with the elements writable and not otherwise borrowed.
pub unsafe fn vector_mut<'a, T>(x: *mut T, len: i64, inc: i64) -> MatMut<'a, T> {
    let start = if inc < 0 && len > 0 { x.offset(((len - 1) * -inc) as isize) } else { x };
    let start = if len == 0 { core::ptr::NonNull::<T>::dangling().as_ptr() } else { start };
    MatMut::from_raw_parts_mut(start, len as usize, 1, inc as isize, 0)
}

/// One BLAS or LAPACK routine, written once over `T` and exported twice: as the double-precision
/// symbol with `T = f64` and the single-precision one with `T = f32`, each in a module of its
/// own (named as the symbol) where `T` names its precision, and re-exported beside it.
macro_rules! exported {
    ($(#[$doc:meta])* $double:ident, $single:ident ($($arg:ident: $ty:ty),* $(,)?) $body:block) => {
        $crate::args::exported!(@one f64, $double, $(#[$doc])* ($($arg: $ty),*) $body);
        $crate::args::exported!(@one f32, $single, $(#[$doc])* ($($arg: $ty),*) $body);
    };
    (@one $real:ty, $name:ident, $(#[$doc:meta])* ($($arg:ident: $ty:ty),*) $body:block) => {
        pub use self::$name::$name;

        #[doc = concat!("`", stringify!($name), "` (the routine over `", stringify!($real), "`).")]
        pub mod $name {
            use super::*;
            type T = $real;

            $(#[$doc])*
            ///
            /// # Safety
            /// The arguments are those of the reference routine, valid for the dimensions they
            /// give.
            #[no_mangle]
            #[allow(clippy::too_many_arguments)]
            pub unsafe extern "C" fn $name($($arg: $ty),*) $body
        }
    };
}
pub(crate) use exported;
