//! Values the scene file reads more strictly than serde would: arrays of an exact length, and a
//! scale that is one number or three.

use std::fmt;

use serde::de::{self, Deserializer, SeqAccess, Visitor};
use serde::Deserialize;

/// A TOML array of exactly `N` values. serde's own `[T; N]` stops reading after `N` and drops
/// the rest without a word, so `eye = [0, 1, 5, 7]` would pass as `[0, 1, 5]`.
pub struct Exact<T, const N: usize>(pub [T; N]);

/// `[x, y, z]`.
pub type Xyz = Exact<f64, 3>;

impl<'de, T: Deserialize<'de>, const N: usize> Deserialize<'de> for Exact<T, N> {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct ExactVisitor<T, const N: usize>(std::marker::PhantomData<T>);
        impl<'de, T: Deserialize<'de>, const N: usize> Visitor<'de> for ExactVisitor<T, N> {
            type Value = Exact<T, N>;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                write!(f, "an array of length {N}")
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Exact<T, N>, A::Error> {
                let mut items = Vec::with_capacity(N);
                while items.len() < N {
                    match seq.next_element::<T>()? {
                        Some(item) => items.push(item),
                        None => return Err(de::Error::invalid_length(items.len(), &self)),
                    }
                }
                // Extra elements of any type count towards the length in the message.
                let mut len = N;
                while seq.next_element::<de::IgnoredAny>()?.is_some() {
                    len += 1;
                }
                if len != N {
                    return Err(de::Error::invalid_length(len, &self));
                }
                match items.try_into() {
                    Ok(array) => Ok(Exact(array)),
                    Err(_) => Err(de::Error::invalid_length(len, &self)), // N items: unreachable
                }
            }
        }
        deserializer.deserialize_seq(ExactVisitor(std::marker::PhantomData))
    }
}

/// `scale = s` or `scale = [sx, sy, sz]`.
pub struct Scale(pub [f64; 3]);

impl<'de> Deserialize<'de> for Scale {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct ScaleVisitor;
        impl<'de> Visitor<'de> for ScaleVisitor {
            type Value = Scale;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a number or an array of 3 numbers")
            }
            fn visit_f64<E: de::Error>(self, s: f64) -> Result<Scale, E> {
                Ok(Scale([s; 3]))
            }
            fn visit_i64<E: de::Error>(self, s: i64) -> Result<Scale, E> {
                Ok(Scale([s as f64; 3]))
            }
            fn visit_u64<E: de::Error>(self, s: u64) -> Result<Scale, E> {
                Ok(Scale([s as f64; 3]))
            }
            fn visit_seq<A: SeqAccess<'de>>(self, seq: A) -> Result<Scale, A::Error> {
                Xyz::deserialize(de::value::SeqAccessDeserializer::new(seq)).map(|xyz| Scale(xyz.0))
            }
        }
        deserializer.deserialize_any(ScaleVisitor)
    }
}
