//! The JSON scene format, as serde types. Every struct denies unknown keys; numbers and
//! vectors have their own types so that a type error reads "expected a number" rather than
//! serde's internal names. Tagged unions (`type`) are dispatched by hand in `load.rs`, which
//! removes the `type` key and deserializes the variant's struct, so that errors inside a
//! variant keep their full JSON path (serde's internally tagged enums lose it).

use std::collections::BTreeMap;
use std::fmt;

use serde::Deserialize;
use serde::de::{self, Deserializer, SeqAccess, Visitor};
use serde_json::Value;

/// A finite JSON number of magnitude at most MAX_MAGNITUDE.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Num(pub f64);

/// Every number in a scene stays within this magnitude, so that it and the sums and
/// squares the engine forms from it (in f32, up to 3.4e38) stay finite.
pub const MAX_MAGNITUDE: f64 = 1e15;

/// `[x, y, z]`: a point, vector or linear RGB colour.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct V3(pub [f64; 3]);

impl<'de> Deserialize<'de> for Num {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Num, D::Error> {
        struct NumVisitor;
        impl Visitor<'_> for NumVisitor {
            type Value = Num;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a number")
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<Num, E> {
                if v.is_finite() && v.abs() <= MAX_MAGNITUDE {
                    Ok(Num(v))
                } else {
                    Err(E::custom(format!(
                        "expected a number of magnitude at most {MAX_MAGNITUDE:e}, got {v:e}"
                    )))
                }
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<Num, E> {
                self.visit_f64(v as f64)
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<Num, E> {
                self.visit_f64(v as f64)
            }
        }
        d.deserialize_any(NumVisitor)
    }
}

impl<'de> Deserialize<'de> for V3 {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<V3, D::Error> {
        struct V3Visitor;
        impl<'de> Visitor<'de> for V3Visitor {
            type Value = V3;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("an array of 3 numbers")
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<V3, A::Error> {
                let mut out = [0.0; 3];
                for (i, slot) in out.iter_mut().enumerate() {
                    match seq.next_element::<Num>()? {
                        Some(Num(v)) => *slot = v,
                        None => return Err(de::Error::invalid_length(i, &self)),
                    }
                }
                if seq.next_element::<de::IgnoredAny>()?.is_some() {
                    return Err(de::Error::custom(
                        "expected an array of 3 numbers, got more",
                    ));
                }
                Ok(V3(out))
            }
        }
        d.deserialize_seq(V3Visitor)
    }
}

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields, expecting = "an object")]
pub struct SceneFile {
    pub camera: CameraDef,
    pub materials: BTreeMap<String, Value>,
    pub objects: Vec<Value>,
    pub lights: Vec<Value>,
    #[serde(default)]
    pub name: Option<String>,
    #[serde(default)]
    pub description: Option<String>,
}

#[derive(Deserialize, Debug, Clone)]
#[serde(deny_unknown_fields, expecting = "an object")]
pub struct CameraDef {
    pub position: V3,
    pub look_at: V3,
    pub up: V3,
    pub fov: Num,
    pub width: u32,
    pub height: u32,
}

// ----- materials -----

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields, expecting = "an object")]
pub struct DiffuseDef {
    pub albedo: V3,
}

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields, expecting = "an object")]
pub struct MirrorDef {
    pub reflectance: V3,
}

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields, expecting = "an object")]
pub struct DielectricDef {
    pub ior: Num,
}

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields, expecting = "an object")]
pub struct PhongDef {
    pub diffuse: V3,
    pub specular: V3,
    pub exponent: Num,
}

// ----- objects -----

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields, expecting = "an object")]
pub struct SphereDef {
    pub material: String,
    pub center: V3,
    pub radius: Num,
}

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields, expecting = "an object")]
pub struct QuadDef {
    pub material: String,
    pub corner: V3,
    pub edge_u: V3,
    pub edge_v: V3,
}

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields, expecting = "an object")]
pub struct MeshDef {
    pub material: String,
    #[serde(default)]
    pub positions: Option<Vec<V3>>,
    #[serde(default)]
    pub triangles: Option<Vec<[u32; 3]>>,
    #[serde(default)]
    pub obj: Option<String>,
}

// ----- lights -----

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields, expecting = "an object")]
pub struct PointLightDef {
    pub position: V3,
    pub power: V3,
}

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields, expecting = "an object")]
pub struct SphereLightDef {
    pub center: V3,
    pub radius: Num,
    pub radiance: V3,
}

#[derive(Deserialize, Debug)]
#[serde(deny_unknown_fields, expecting = "an object")]
pub struct QuadLightDef {
    pub corner: V3,
    pub edge_u: V3,
    pub edge_v: V3,
    pub radiance: V3,
}
