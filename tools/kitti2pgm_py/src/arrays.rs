//! Numpy arguments: checked for type, dtype and shape, with a `ValueError` that names the
//! argument and says what it got.

use numpy::{Element, PyArrayDescrMethods, PyArrayDyn, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use kitti2pgm::geom::Point3;
pub use kitti2pgm::simd::{with_avx2, with_simd};

/// "float64 array of shape (3, 4)" or the Python type of a non-array.
fn describe(obj: &Bound<'_, PyAny>) -> String {
    match obj.cast::<numpy::PyUntypedArray>() {
        Ok(a) => {
            let dims: Vec<String> = a.shape().iter().map(usize::to_string).collect();
            let comma = if dims.len() == 1 { "," } else { "" };
            format!(
                "a {} array of shape ({}{comma})",
                a.dtype().str().map(|s| s.to_string()).unwrap_or_default(),
                dims.join(", ")
            )
        }
        Err(_) => format!(
            "a {}",
            obj.get_type()
                .name()
                .map(|n| n.to_string())
                .unwrap_or_default()
        ),
    }
}

/// An array of another numeric dtype as one of element type `T` (numpy's `astype`, one copy),
/// by the module's one rule: float and integer arrays convert to float32; integer arrays convert
/// to an integer type when every value fits (else `ValueError` naming the value); bool arrays
/// only to bool; nothing converts silently with rounding or wrapping. `None` when `obj` is no
/// numpy array or its dtype does not convert.
fn converted<'py, T: Element + DtypeName>(
    obj: &Bound<'py, PyAny>,
    name: &str,
) -> PyResult<Option<Bound<'py, PyAny>>> {
    let Ok(a) = obj.cast::<numpy::PyUntypedArray>() else {
        return Ok(None);
    };
    let kind = a.dtype().kind() as char;
    let ok = match T::KIND {
        'f' => matches!(kind, 'f' | 'i' | 'u'),
        'u' | 'i' => matches!(kind, 'i' | 'u'),
        'b' => kind == 'b',
        _ => false,
    };
    if !ok {
        return Ok(None);
    }
    if matches!(T::KIND, 'u' | 'i') && a.len() > 0 {
        for (what, bound) in [("min", T::MIN), ("max", T::MAX)] {
            let v: f64 = obj.call_method0(what)?.extract()?;
            let outside = if what == "min" { v < bound } else { v > bound };
            if outside {
                return Err(PyValueError::new_err(format!(
                    "{name} holds {v}, which does not fit {} ({}..={})",
                    T::NAME,
                    T::MIN,
                    T::MAX
                )));
            }
        }
    }
    Ok(Some(obj.call_method1("astype", (T::NAME,))?))
}

/// `f` of the values of an array of element type `T`, row-major, and its shape: the array's own
/// memory when it is C-contiguous, else a row-major copy (Fortran-ordered and strided arrays
/// are read in their logical order, never as their memory lies).
fn with_values<T: Element + Copy + DtypeName, R>(
    obj: &Bound<'_, PyAny>,
    name: &str,
    want: &str,
    f: impl FnOnce(&[T], &[usize]) -> PyResult<R>,
) -> PyResult<R> {
    let conv;
    let arr = match obj.cast::<PyArrayDyn<T>>() {
        Ok(a) => a,
        Err(_) => {
            conv = converted::<T>(obj, name)?.ok_or_else(|| {
                PyValueError::new_err(format!("{name} must be {want}, got {}", describe(obj)))
            })?;
            conv.cast::<PyArrayDyn<T>>().map_err(|_| {
                PyValueError::new_err(format!("{name}: conversion to {} failed", T::NAME))
            })?
        }
    };
    let ro = arr.readonly();
    let shape = ro.shape().to_vec();
    if arr.is_c_contiguous() {
        // (`as_slice` also accepts Fortran-contiguous arrays, whose memory is column-major:
        // only a C-contiguous array's memory is its row-major values.)
        if let Ok(s) = ro.as_slice() {
            return f(s, &shape);
        }
        // Contiguous but not aligned for T (arrays viewing a shard message's bytes): one byte
        // copy into aligned memory.
        let n = arr.len();
        let mut v: Vec<T> = Vec::with_capacity(n);
        // SAFETY: a C-contiguous array of n elements of T spans n * size_of::<T>() readable
        // bytes from its data pointer (numpy's guarantee); `v` has room for n elements; every
        // bit pattern is a valid T for the plain number and bool types used here (numpy
        // stores bools as 0 or 1).
        unsafe {
            std::ptr::copy_nonoverlapping(
                arr.data() as *const u8,
                v.as_mut_ptr() as *mut u8,
                n * std::mem::size_of::<T>(),
            );
            v.set_len(n);
        }
        return f(&v, &shape);
    }
    let v: Vec<T> = ro.as_array().iter().copied().collect();
    f(&v, &shape)
}

/// The values of an array of element type `T`, row-major, with its shape (one copy).
fn values<T: Element + Copy + DtypeName>(
    obj: &Bound<'_, PyAny>,
    name: &str,
    want: &str,
) -> PyResult<(Vec<T>, Vec<usize>)> {
    with_values(obj, name, want, |v: &[T], shape| {
        Ok((v.to_vec(), shape.to_vec()))
    })
}

/// Points from an (N, 3) or (N, 4) float32 array; with `intensity`, (N, 4) is required and the
/// fourth column is returned too.
pub fn points_arg(
    obj: &Bound<'_, PyAny>,
    name: &str,
    intensity: bool,
) -> PyResult<(Vec<Point3>, Option<Vec<f32>>)> {
    let want = if intensity {
        "a float32 array of shape (N, 4): x, y, z, intensity"
    } else {
        "a float32 array of shape (N, 3) or (N, 4)"
    };
    with_values(obj, name, want, |v: &[f32], shape| {
        let cols = match shape[..] {
            [_, 4] => 4,
            [_, 3] if !intensity => 3,
            _ => {
                return Err(PyValueError::new_err(format!(
                    "{name} must be {want}, got {}",
                    describe(obj)
                )))
            }
        };
        if !intensity {
            let pts = v.chunks_exact(cols).map(|r| Point3::new(r[0], r[1], r[2]));
            return Ok((pts.collect(), None));
        }
        // One pass for both.
        let (pts, inten) = with_simd(
            #[inline(always)]
            || {
                let (rows, _) = v.as_chunks::<4>();
                unzip_map(rows, |r| (Point3::new(r[0], r[1], r[2]), r[3]))
            },
        );
        Ok((pts, Some(inten)))
    })
}

/// The rows of an (N, 3) or (N, 4) float32 array of points (x, y, z first).
#[derive(Clone, Copy)]
pub enum PointRows<'a> {
    /// x, y, z.
    Three(&'a [[f32; 3]]),
    /// x, y, z and a fourth value (intensity).
    Four(&'a [[f32; 4]]),
}

impl PointRows<'_> {
    /// The points.
    pub fn len(&self) -> usize {
        match self {
            PointRows::Three(r) => r.len(),
            PointRows::Four(r) => r.len(),
        }
    }
}

/// `f` of the rows of an (N, 3) or (N, 4) float32 array of points, read in place.
pub fn with_point_rows<R>(
    obj: &Bound<'_, PyAny>,
    name: &str,
    f: impl FnOnce(PointRows<'_>) -> PyResult<R>,
) -> PyResult<R> {
    let want = "a float32 array of shape (N, 3) or (N, 4)";
    with_values(obj, name, want, |v: &[f32], shape| match shape[..] {
        [_, 3] => f(PointRows::Three(v.as_chunks::<3>().0)),
        [_, 4] => f(PointRows::Four(v.as_chunks::<4>().0)),
        _ => Err(PyValueError::new_err(format!(
            "{name} must be {want}, got {}",
            describe(obj)
        ))),
    })
}

/// `f` of every value of `input`, its pairs as two vectors, each slot written once: no zero
/// fill first, no growth check per value, one loop over three slices of one length, which the
/// compiler vectorises (a loop over a generic iterator of pairs it did not: the row / col split
/// ran a value at a time). Both uses cost a tenth of a `project` call.
#[inline(always)]
pub fn unzip_map<T: Copy, A, B>(input: &[T], f: impl Fn(T) -> (A, B)) -> (Vec<A>, Vec<B>) {
    let n = input.len();
    let (mut a, mut b) = (Vec::with_capacity(n), Vec::with_capacity(n));
    let slots = a.spare_capacity_mut()[..n].iter_mut();
    for ((sa, sb), &x) in slots.zip(&mut b.spare_capacity_mut()[..n]).zip(input) {
        let (x, y) = f(x);
        sa.write(x);
        sb.write(y);
    }
    // SAFETY: the loop wrote the first `n` slots of both.
    unsafe {
        a.set_len(n);
        b.set_len(n);
    }
    (a, b)
}

/// `f` of every value of `input`, collected without a zero fill first (a `memset` of the whole
/// output, then overwritten): one loop over two slices of one length, which vectorises.
#[inline(always)]
pub fn map_exact<T: Copy, A>(input: &[T], mut f: impl FnMut(T) -> A) -> Vec<A> {
    let n = input.len();
    let mut out = Vec::with_capacity(n);
    for (o, &x) in out.spare_capacity_mut()[..n].iter_mut().zip(input) {
        o.write(f(x));
    }
    // SAFETY: the loop wrote the first `n` slots.
    unsafe { out.set_len(n) };
    out
}

/// A one-dimensional array of `n` entries of type `T` (`dtype` names it in the message).
pub fn vec_arg<T: Element + Copy + DtypeName>(
    obj: &Bound<'_, PyAny>,
    name: &str,
    n: usize,
) -> PyResult<Vec<T>> {
    with_vec(obj, name, n, |v: &[T]| Ok(v.to_vec()))
}

/// `f` of a one-dimensional array of `n` entries of type `T`, read in place where it can be
/// (as [`vec_arg`] checks it, without the copy).
pub fn with_vec<T: Element + Copy + DtypeName, R>(
    obj: &Bound<'_, PyAny>,
    name: &str,
    n: usize,
    f: impl FnOnce(&[T]) -> PyResult<R>,
) -> PyResult<R> {
    let want = format!("a {} array of shape ({n},)", T::NAME);
    with_values(obj, name, &want, |v: &[T], shape| {
        if shape != [n] {
            return Err(PyValueError::new_err(format!(
                "{name} must be {want} (one per point), got {}",
                describe(obj)
            )));
        }
        f(v)
    })
}

/// A one-dimensional array of type `T`, of any length (one copy).
pub fn list_arg<T: Element + Copy + DtypeName>(
    obj: &Bound<'_, PyAny>,
    name: &str,
) -> PyResult<Vec<T>> {
    let want = format!("a one-dimensional {} array", T::NAME);
    let (v, shape) = values::<T>(obj, name, &want)?;
    if shape.len() != 1 {
        return Err(PyValueError::new_err(format!(
            "{name} must be {want}, got {}",
            describe(obj)
        )));
    }
    Ok(v)
}

/// Colours from an (N, 3) float32 array.
pub fn colours_arg(obj: &Bound<'_, PyAny>, n: usize) -> PyResult<Vec<[f32; 3]>> {
    let want = format!("a float32 array of shape ({n}, 3) (r, g, b in [0, 1])");
    let (v, shape) = values::<f32>(obj, "rgb", &want)?;
    if shape != [n, 3] {
        return Err(PyValueError::new_err(format!(
            "rgb must be {want}, got {}",
            describe(obj)
        )));
    }
    // The colours `convert --rgb` samples are in [0, 1]; anything else (NaN, 255-scale, -7)
    // would enter the map as it is.
    if let Some((i, c)) = v
        .iter()
        .enumerate()
        .find(|(_, c)| !(0.0..=1.0).contains(*c))
    {
        return Err(PyValueError::new_err(format!(
            "rgb: value {} (point {}, channel {}) is outside [0, 1]",
            kitti2pgm::error::shown(*c),
            i / 3,
            ["r", "g", "b"][i % 3]
        )));
    }
    Ok(v.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect())
}

/// The numpy name, kind and largest value of an element type (messages and conversion).
pub trait DtypeName {
    /// e.g. `uint8`.
    const NAME: &'static str;
    /// numpy's dtype kind: `f`, `u` or `b`.
    const KIND: char;
    /// The smallest value.
    const MIN: f64 = 0.0;
    /// The largest value.
    const MAX: f64;
}

impl DtypeName for u8 {
    const NAME: &'static str = "uint8";
    const KIND: char = 'u';
    const MAX: f64 = u8::MAX as f64;
}
impl DtypeName for u16 {
    const NAME: &'static str = "uint16";
    const KIND: char = 'u';
    const MAX: f64 = u16::MAX as f64;
}
impl DtypeName for bool {
    const NAME: &'static str = "bool";
    const KIND: char = 'b';
    const MAX: f64 = 1.0;
}
impl DtypeName for i32 {
    const NAME: &'static str = "int32";
    const KIND: char = 'i';
    const MIN: f64 = i32::MIN as f64;
    const MAX: f64 = i32::MAX as f64;
}
impl DtypeName for i64 {
    const NAME: &'static str = "int64";
    const KIND: char = 'i';
    const MIN: f64 = i64::MIN as f64;
    const MAX: f64 = i64::MAX as f64;
}
impl DtypeName for f32 {
    const NAME: &'static str = "float32";
    const KIND: char = 'f';
    const MIN: f64 = f32::MIN as f64;
    const MAX: f64 = f32::MAX as f64;
}

/// A two-dimensional array of type `T` with its shape (rows, cols), row-major (one copy).
pub fn grid_arg<T: Element + Copy + DtypeName>(
    obj: &Bound<'_, PyAny>,
    name: &str,
) -> PyResult<(Vec<T>, usize, usize)> {
    with_grid(obj, name, |v: &[T], h, w| Ok((v.to_vec(), h, w)))
}

/// `f` of a two-dimensional array of type `T`, row-major, and its shape (rows, cols): read in
/// place where it can be (as [`grid_arg`] checks it, without the copy).
pub fn with_grid<T: Element + Copy + DtypeName, R>(
    obj: &Bound<'_, PyAny>,
    name: &str,
    f: impl FnOnce(&[T], usize, usize) -> PyResult<R>,
) -> PyResult<R> {
    let want = format!("a {} array of shape (H, W)", T::NAME);
    with_values(obj, name, &want, |v: &[T], shape| match shape[..] {
        [h, w] => f(v, h, w),
        _ => Err(PyValueError::new_err(format!(
            "{name} must be {want}, got {}",
            describe(obj)
        ))),
    })
}
