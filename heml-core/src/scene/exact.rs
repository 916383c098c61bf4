//! Fixed-length arrays in scene files: exactly N elements. serde's own arrays stop
//! reading after N elements and the TOML reader does not object to the rest, so
//! `gravity = [0, 0, -9.81, 1]` or a quaternion given as `rotation` ran with the
//! extra numbers dropped; these helpers make every 3-vector, point pair and
//! keyframe row of a scene an error unless it has exactly its length (the error
//! carries the TOML span, so the message names the line).

use std::fmt;
use std::marker::PhantomData;

use serde::de::{Deserialize, Deserializer, Error, IgnoredAny, SeqAccess, Visitor};

/// `[T; N]`, deserialized from an array of exactly N elements.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Exact<T, const N: usize>(pub [T; N]);

struct ExactVisitor<T, const N: usize>(PhantomData<T>);

impl<'de, T: Deserialize<'de>, const N: usize> Visitor<'de> for ExactVisitor<T, N> {
    type Value = Exact<T, N>;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "an array of {N} elements")
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Self::Value, A::Error> {
        let mut items = Vec::with_capacity(N);
        while items.len() < N {
            match seq.next_element()? {
                Some(x) => items.push(x),
                None => return Err(A::Error::invalid_length(items.len(), &self)),
            }
        }
        // one element more is enough to refuse: a huge array is not read to its end
        if seq.next_element::<IgnoredAny>()?.is_some() {
            return Err(A::Error::custom(format_args!(
                "invalid length: more than {N} elements, expected an array of {N} elements"
            )));
        }
        let items: [T; N] = items
            .try_into()
            .map_err(|_| A::Error::custom("internal error: array length"))?;
        Ok(Exact(items))
    }
}

impl<'de, T: Deserialize<'de>, const N: usize> Deserialize<'de> for Exact<T, N> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_seq(ExactVisitor(PhantomData))
    }
}

/// Exactly three numbers.
pub(super) fn vec3<'de, D: Deserializer<'de>>(d: D) -> Result<[f64; 3], D::Error> {
    Exact::<f64, 3>::deserialize(d).map(|e| e.0)
}

/// An optional 3-vector (use with `#[serde(default)]`).
pub(super) fn opt_vec3<'de, D: Deserializer<'de>>(d: D) -> Result<Option<[f64; 3]>, D::Error> {
    Option::<Exact<f64, 3>>::deserialize(d).map(|o| o.map(|e| e.0))
}

/// Optional rows of exactly N numbers each (fibre directions, keyframes).
pub(super) fn opt_rows<'de, D: Deserializer<'de>, const N: usize>(d: D) -> Result<Option<Vec<[f64; N]>>, D::Error> {
    Option::<Vec<Exact<f64, N>>>::deserialize(d).map(|o| o.map(|rows| rows.into_iter().map(|r| r.0).collect()))
}

/// Optional M points of exactly three coordinates (a blade's edge or triangle).
pub(super) fn opt_points<'de, D: Deserializer<'de>, const M: usize>(d: D) -> Result<Option<[[f64; 3]; M]>, D::Error> {
    Option::<Exact<Exact<f64, 3>, M>>::deserialize(d).map(|o| o.map(|p| p.0.map(|e| e.0)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, serde::Deserialize)]
    struct Probe {
        #[serde(deserialize_with = "vec3")]
        v: [f64; 3],
        #[serde(default, deserialize_with = "opt_points")]
        edge: Option<[[f64; 3]; 2]>,
    }

    #[test]
    fn arrays_must_have_exactly_their_length() {
        let ok: Probe = toml::from_str("v = [1, 2, 3]\nedge = [[0, 0, 0], [1, 1, 1]]").unwrap();
        assert_eq!((ok.v, ok.edge.unwrap()[1]), ([1.0, 2.0, 3.0], [1.0; 3]));
        assert!(toml::from_str::<Probe>("v = [1, 2, 3]").unwrap().edge.is_none());
        let err = |t: &str| toml::from_str::<Probe>(t).unwrap_err().to_string();
        let long = err("v = [1, 2, 3, 4]");
        assert!(
            long.contains("more than 3 elements") && long.contains("line 1"),
            "{long}"
        );
        assert!(err("v = [1, 2]").contains("invalid length 2"), "{}", err("v = [1, 2]"));
        assert!(err("v = [1, 2, 3, \"x\"]").contains("more than 3"));
        let edge = err("v = [1, 2, 3]\nedge = [[0, 0, 0], [1, 1, 1, 1]]");
        assert!(edge.contains("more than 3") && edge.contains("line 2"), "{edge}");
        assert!(err("v = [1, 2, 3]\nedge = [[0, 0, 0], [1, 1, 1], [2, 2, 2]]").contains("more than 2"));
    }
}
