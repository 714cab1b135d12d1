//! The scene parser never panics (issue 5): proptest feeds it (a) arbitrary text, (b)
//! arbitrary JSON values of bounded depth, values shaped like a scene and well-formed scenes
//! with extreme numbers, and (c) valid scenes (scenes/cornell.json, scenes/glass_orange.json)
//! with JSON nodes replaced, deleted or inserted at random paths. Whatever the input, parsing
//! returns, and an error has a path and a message; an accepted scene builds and renders
//! (raytrace, 4x4, 1 spp) to finite pixels with no non-finite sample. Two more properties:
//! every error is one line, and an accepted scene is sane (`check_scene`).
//!
//! The suite's case counts keep the file at a few seconds; `PROPTEST_CASES=N` sets every
//! test's count to N for a longer run (docs/fuzzing.md).

mod common;

use photonbox::render::geometry::Surface;
use photonbox::render::scene::{LightDesc, ShapeDesc};
use photonbox::render::{Control, Scene, SceneDesc, SceneError, render};
use photonbox::spec::RenderSpec;
use proptest::prelude::*;
use proptest::sample::Index;
use serde_json::{Map, Value, json};

const CORNELL: &str = include_str!("../scenes/cornell.json");
const GLASS_ORANGE: &str = include_str!("../scenes/glass_orange.json");

// ----- the checks -----

/// An error names a path and says what is wrong.
fn check_error(e: &SceneError) -> Result<(), TestCaseError> {
    prop_assert!(
        !e.path.is_empty() && !e.message.is_empty(),
        "empty error part: {:?}",
        e
    );
    Ok(())
}

/// The CLI prints an error as one line (README, "Bad input exits with code 2 and one line").
fn check_one_line(e: &SceneError) -> Result<(), TestCaseError> {
    let line = e.to_string();
    prop_assert!(
        !line.contains(['\n', '\r']),
        "error is not one line: {:?}",
        line
    );
    Ok(())
}

/// What parsing gave, once it passed the checks every input must pass.
enum Parsed {
    Rejected(SceneError),
    Accepted(Box<(SceneDesc, Scene)>),
}

/// Parse `text` with both entry points and check what must hold for any input: parsing
/// returns (the test fails on a panic), an error has a path and a message, and an accepted
/// scene builds and renders (raytrace, 4x4, 1 spp) to finite pixels with no non-finite
/// sample.
fn parse_and_render(text: &str) -> Result<Parsed, TestCaseError> {
    let desc = match SceneDesc::parse(text, None) {
        Ok(d) => d,
        Err(e) => {
            check_error(&e)?;
            // The full entry point fails the same way.
            let e2 = Scene::parse(text, None).err();
            prop_assert_eq!(e2.as_ref(), Some(&e));
            return Ok(Parsed::Rejected(e));
        }
    };
    let scene = Scene::parse(text, None).expect("SceneDesc parsed, so Scene parses");
    let params = RenderSpec {
        width: Some(4),
        height: Some(4),
        ..RenderSpec::raytrace(1)
    };
    params.validate().expect("valid render parameters");
    let out = render(&scene, &params, &Control::none()).expect("not cancelled");
    prop_assert_eq!(out.image.pixels.len(), 16);
    prop_assert!(
        out.image.pixels.iter().flatten().all(|c| c.is_finite()),
        "non-finite pixels: {:?}",
        out.image.pixels
    );
    // The film drops non-finite samples, so finite pixels alone would prove little.
    prop_assert_eq!(
        out.stats.nonfinite_samples,
        0,
        "samples dropped as non-finite"
    );
    Ok(Parsed::Accepted(Box::new((desc, scene))))
}

/// An accepted scene is what its description says, in finite coordinates: the primitives
/// and lights it lists, surfaces that name existing materials and lights, finite bounds and
/// extent, and a camera whose rays have finite directions.
fn check_scene(desc: &SceneDesc, scene: &Scene) -> Result<(), TestCaseError> {
    prop_assert_eq!(scene.materials.len(), desc.materials.len());
    prop_assert_eq!(scene.material_names.len(), desc.materials.len());
    prop_assert_eq!(scene.lights.len(), desc.lights.len());
    let mut prims = 0;
    let mut triangles = 0;
    for o in &desc.objects {
        match &o.shape {
            ShapeDesc::Mesh(m) => {
                prims += m.triangles.len();
                triangles += m.triangles.len();
            }
            _ => prims += 1,
        }
    }
    prims += desc
        .lights
        .iter()
        .filter(|l| !matches!(l, LightDesc::Point { .. }))
        .count();
    prop_assert_eq!(scene.triangle_count, triangles);
    prop_assert_eq!(scene.accel.prims().len(), prims);
    for p in scene.accel.prims() {
        match p.surface {
            Surface::Material(m) => prop_assert!((m as usize) < scene.materials.len()),
            Surface::Light(l) => prop_assert!((l as usize) < scene.lights.len()),
        }
    }
    prop_assert!(scene.frame_origin.is_finite(), "{:?}", scene.frame_origin);
    prop_assert!(
        scene.bounds_min.is_finite()
            && scene.bounds_max.is_finite()
            && scene.bounds_min.cmple(scene.bounds_max).all(),
        "bounds {:?} {:?}",
        scene.bounds_min,
        scene.bounds_max
    );
    prop_assert!(
        scene.geometry_extent.is_finite() && scene.geometry_extent >= 0.0,
        "extent {}",
        scene.geometry_extent
    );
    let c = &scene.camera;
    prop_assert!(c.position.is_finite(), "camera at {:?}", c.position);
    let (w, h) = (c.width as f32, c.height as f32);
    for (x, y) in [(0.0, 0.0), (w, 0.0), (0.0, h), (w, h), (w * 0.5, h * 0.5)] {
        let d = c.ray(x, y).d;
        prop_assert!(d.is_finite(), "camera ray through ({}, {}): {:?}", x, y, d);
    }
    Ok(())
}

// ----- strategies -----

/// The scene format's words: keys, type tags, a material name.
const WORDS: &[&str] = &[
    "camera",
    "materials",
    "objects",
    "lights",
    "name",
    "description",
    "position",
    "look_at",
    "up",
    "fov",
    "width",
    "height",
    "type",
    "albedo",
    "reflectance",
    "ior",
    "diffuse",
    "specular",
    "exponent",
    "mirror",
    "dielectric",
    "phong",
    "material",
    "center",
    "radius",
    "corner",
    "edge_u",
    "edge_v",
    "positions",
    "triangles",
    "obj",
    "sphere",
    "quad",
    "mesh",
    "point",
    "power",
    "radiance",
    "white",
    "glass",
];

/// Numbers at the edges of what the loader accepts and beyond.
const SPECIAL_NUMBERS: &[f64] = &[
    0.0,
    -0.0,
    1.0,
    -1.0,
    0.5,
    1.000001,
    1.0000011,
    179.999,
    180.0,
    16384.0,
    16385.0,
    1e-300,
    5e-324,
    f64::MIN_POSITIVE,
    1e-10,
    1e-7,
    1e6,
    1e6 + 1.0,
    1e15,
    1.0000000000000002e15,
    -1e15,
    1e16,
    3.5e38,
    -3.5e38,
    1e300,
    -1e308,
    f64::MAX,
    4294967295.0,
    4294967296.0,
    9007199254740993.0,
];

fn word() -> impl Strategy<Value = String> {
    prop::sample::select(WORDS).prop_map(String::from)
}

fn key() -> impl Strategy<Value = String> {
    prop_oneof![
        6 => word(),
        2 => ".{0,8}",
        1 => prop::sample::select(vec![
            "", "\n", "a\nb", "\r\n", "\t", "\"", "\\", "\u{0}", "\u{2028}", "é",
        ])
        .prop_map(String::from),
    ]
}

fn number() -> impl Strategy<Value = Value> {
    prop_oneof![
        3 => prop::sample::select(SPECIAL_NUMBERS).prop_map(|x| json!(x)),
        2 => (-3i64..20).prop_map(|x| json!(x)),
        1 => any::<i64>().prop_map(|x| json!(x)),
        1 => any::<u64>().prop_map(|x| json!(x)),
        1 => any::<u32>().prop_map(|x| json!(x)),
        2 => (-10.0f64..10.0).prop_map(|x| json!(x)),
        // Finite f64s of any magnitude (json! of a non-finite one would be null).
        1 => any::<f64>().prop_map(|x| json!(x)),
    ]
}

fn string() -> impl Strategy<Value = Value> {
    prop_oneof![
        3 => word(),
        1 => prop::sample::select(vec![
            "NaN", "nan", "inf", "-Infinity", "1e999", "0x10", "", " ", "1", "../x.obj",
            "/etc/passwd", "\u{0}", "é\n\t\"\\",
        ])
        .prop_map(String::from),
        1 => ".{0,16}",
    ]
    .prop_map(Value::String)
}

fn leaf() -> impl Strategy<Value = Value> {
    prop_oneof![
        1 => Just(Value::Null),
        1 => any::<bool>().prop_map(Value::Bool),
        4 => number(),
        2 => string(),
        1 => Just(json!([])),
        1 => Just(json!({})),
    ]
}

/// Any JSON value, at most `depth` levels of containers deep.
fn value(depth: u32) -> impl Strategy<Value = Value> {
    leaf().prop_recursive(depth, 48, 6, |inner| {
        prop_oneof![
            prop::collection::vec(inner.clone(), 0..6).prop_map(Value::Array),
            prop::collection::vec((key(), inner), 0..6)
                .prop_map(|kv| Value::Object(kv.into_iter().collect::<Map<_, _>>())),
        ]
    })
}

/// `[x, y, z]` of awkward numbers, or a near miss.
fn vec3() -> impl Strategy<Value = Value> {
    prop_oneof![
        4 => prop::array::uniform3(number()).prop_map(|a| Value::Array(a.to_vec())),
        2 => prop::array::uniform3(-5.0f64..5.0).prop_map(|a| json!(a)),
        1 => prop::collection::vec(number(), 0..5).prop_map(Value::Array),
        1 => leaf(),
    ]
}

/// A value for a field of the scene format.
fn field() -> impl Strategy<Value = Value> {
    prop_oneof![4 => vec3(), 2 => number(), 1 => string(), 1 => value(2)]
}

/// An object with a `type` tag from `tags` and fields from the format's words.
fn tagged(tags: &'static [&'static str]) -> impl Strategy<Value = Value> {
    (
        prop::sample::select(tags),
        prop::collection::vec((word(), field()), 0..6),
        prop::option::of(mesh_arrays()),
    )
        .prop_map(|(tag, fields, mesh)| {
            let mut m: Map<String, Value> = fields.into_iter().collect();
            m.insert("type".into(), json!(tag));
            if let Some((p, t)) = mesh {
                m.insert("positions".into(), p);
                m.insert("triangles".into(), t);
            }
            Value::Object(m)
        })
}

/// Mesh positions and triangles, with indices in and out of range (up to u32::MAX and
/// beyond) and, often, enough triangles to need a BVH.
fn mesh_arrays() -> impl Strategy<Value = (Value, Value)> {
    let index = prop_oneof![
        8 => 0u64..40,
        1 => prop::sample::select(vec![4294967295u64, 4294967296, 18446744073709551615]),
    ];
    (
        prop::collection::vec(vec3(), 0..40),
        prop::collection::vec(prop::array::uniform3(index), 0..40),
    )
        .prop_map(|(p, t)| (Value::Array(p), json!(t)))
}

/// A value shaped like a scene: the four sections with plausible and implausible contents.
fn scene_like() -> impl Strategy<Value = Value> {
    let camera = prop::collection::vec((word(), field()), 0..8)
        .prop_map(|kv| Value::Object(kv.into_iter().collect()));
    let materials = prop::collection::vec(
        (
            key(),
            tagged(&["diffuse", "mirror", "dielectric", "phong", "metal"]),
        ),
        0..4,
    )
    .prop_map(|kv| Value::Object(kv.into_iter().collect()));
    let objects = prop::collection::vec(tagged(&["sphere", "quad", "mesh", "cube"]), 0..4)
        .prop_map(Value::Array);
    let lights = prop::collection::vec(tagged(&["point", "sphere", "quad", "spot"]), 0..3)
        .prop_map(Value::Array);
    (camera, materials, objects, lights)
        .prop_map(|(c, m, o, l)| json!({"camera": c, "materials": m, "objects": o, "lights": l}))
}

/// A coordinate: mostly ordinary, else of any magnitude up to the loader's limit (1e15),
/// or one of the special numbers (a third of which the loader refuses).
fn coord() -> impl Strategy<Value = f64> {
    prop_oneof![
        20 => -5.0f64..5.0,
        2 => (-3i32..=3).prop_map(f64::from),
        6 => (-16.0f64..15.0, any::<bool>())
            .prop_map(|(e, neg)| if neg { -(10f64.powf(e)) } else { 10f64.powf(e) }),
        1 => prop::sample::select(SPECIAL_NUMBERS),
    ]
}

fn point() -> impl Strategy<Value = Value> {
    prop::array::uniform3(coord()).prop_map(|a| json!(a))
}

/// A reflectance channel: in [0, 1], now and then at or just past an end.
fn channel() -> impl Strategy<Value = f64> {
    prop_oneof![
        30 => 0.0f64..=1.0,
        1 => prop::sample::select(vec![0.0, -0.0, 1.0, 1.0000001, 1.000002, -1e-300, 2.0, 1e15]),
    ]
}

fn colour() -> impl Strategy<Value = Value> {
    prop::array::uniform3(channel()).prop_map(|a| json!(a))
}

/// Light power or radiance: any size.
fn emission() -> impl Strategy<Value = Value> {
    let c = prop_oneof![
        8 => 0.0f64..100.0,
        2 => (0.0f64..15.0).prop_map(|e| 10f64.powf(e)),
        1 => prop::sample::select(SPECIAL_NUMBERS),
    ];
    prop::array::uniform3(c).prop_map(|a| json!(a))
}

/// A number for a scalar field, mostly in `ordinary`, else one of the special numbers.
fn scalar(ordinary: std::ops::Range<f64>) -> impl Strategy<Value = Value> {
    prop_oneof![
        8 => ordinary.prop_map(|x| json!(x)),
        1 => prop::sample::select(SPECIAL_NUMBERS).prop_map(|x| json!(x)),
    ]
}

/// A scene that is well formed (every section, key and type right) with extreme numbers:
/// these get past the parser to the validation, the build, the BVH and the render.
fn extreme_scene() -> impl Strategy<Value = Value> {
    const NAMES: &[&str] = &["m0", "m1", "m2"];
    let side = prop_oneof![
        12 => (1u64..48).prop_map(|x| json!(x)),
        1 => prop::sample::select(vec![0u64, 16384, 16385, 4294967295, 4294967296])
            .prop_map(|x| json!(x)),
    ];
    let camera = (
        point(),
        point(),
        point(),
        scalar(1.0..179.0),
        side.clone(),
        side,
    )
        .prop_map(|(position, look_at, up, fov, width, height)| {
            json!({"position": position, "look_at": look_at, "up": up, "fov": fov,
                   "width": width, "height": height})
        });
    let material = prop_oneof![
        colour().prop_map(|c| json!({"type": "diffuse", "albedo": c})),
        colour().prop_map(|c| json!({"type": "mirror", "reflectance": c})),
        scalar(0.3..3.0).prop_map(|x| json!({"type": "dielectric", "ior": x})),
        // kd + ks <= 1 mostly, from a fraction t of what kd leaves.
        (
            prop::array::uniform3(channel()),
            prop::array::uniform3(channel()),
            scalar(0.0..1000.0)
        )
            .prop_map(|(d, t, e)| {
                let s: Vec<f64> = d.iter().zip(t).map(|(d, t)| t * (1.0 - d)).collect();
                json!({"type": "phong", "diffuse": d, "specular": s, "exponent": e})
            }),
    ];
    let materials = prop::collection::vec(material, NAMES.len()).prop_map(|ms| {
        Value::Object(
            ms.into_iter()
                .zip(NAMES)
                .map(|(m, n)| (n.to_string(), m))
                .collect(),
        )
    });
    let name = prop_oneof![30 => prop::sample::select(NAMES), 1 => Just("nope")];
    // Three distinct indices among the first 8 of 8-24 positions, now and then one out of
    // range.
    let triangle = prop_oneof![
        30 => (0u64..8, 1u64..8, 1u64..7).prop_map(|(a, d1, d2)| {
            let d2 = if d2 >= d1 { d2 + 1 } else { d2 };
            [a, (a + d1) % 8, (a + d2) % 8]
        }),
        1 => prop::array::uniform3(0u64..30),
    ];
    let mesh = (
        prop::collection::vec(point(), 8..24),
        prop::collection::vec(triangle, 1..40),
    )
        .prop_map(|(p, t)| (Value::Array(p), json!(t)));
    let object = prop_oneof![
        (name.clone(), point(), scalar(0.01..5.0)).prop_map(|(m, c, r)| {
            json!({"type": "sphere", "material": m, "center": c, "radius": r})
        }),
        (name.clone(), point(), point(), point()).prop_map(|(m, c, u, v)| {
            json!({"type": "quad", "material": m, "corner": c, "edge_u": u, "edge_v": v})
        }),
        (name, mesh).prop_map(|(m, (p, t))| {
            json!({"type": "mesh", "material": m, "positions": p, "triangles": t})
        }),
    ];
    let light = prop_oneof![
        (point(), emission())
            .prop_map(|(p, c)| json!({"type": "point", "position": p, "power": c})),
        (point(), scalar(0.01..5.0), emission()).prop_map(|(c, r, l)| {
            json!({"type": "sphere", "center": c, "radius": r, "radiance": l})
        }),
        (point(), point(), point(), emission()).prop_map(|(c, u, v, l)| {
            json!({"type": "quad", "corner": c, "edge_u": u, "edge_v": v, "radiance": l})
        }),
    ];
    (
        camera,
        materials,
        prop::collection::vec(object, 0..6),
        prop::collection::vec(light, 0..3),
    )
        .prop_map(|(c, m, o, l)| json!({"camera": c, "materials": m, "objects": o, "lights": l}))
}

/// A value for a mutation: anything, with the format's edge cases drawn often.
fn replacement() -> impl Strategy<Value = Value> {
    prop_oneof![
        4 => leaf(),
        2 => vec3(),
        2 => value(3),
        1 => tagged(&["sphere", "quad", "mesh", "point", "diffuse", "phong", "dielectric"]),
        1 => mesh_arrays().prop_map(|(p, t)| {
            json!({"type": "mesh", "material": "white", "positions": p, "triangles": t})
        }),
        // Deep nesting, past serde_json's recursion limit (128) of the text parser.
        1 => (1usize..160, any::<bool>()).prop_map(|(d, arrays)| {
            (0..d).fold(json!(1), |v, _| if arrays { json!([v]) } else { json!({"a": v}) })
        }),
    ]
}

#[derive(Clone, Debug)]
enum Op {
    Replace(Value),
    Delete,
    Insert(String, Value),
}

#[derive(Clone, Debug)]
struct Mutation {
    path: Vec<Index>,
    op: Op,
}

fn mutation() -> impl Strategy<Value = Mutation> {
    let op = prop_oneof![
        3 => prop_oneof![coord().prop_map(|x| json!(x)), point(), colour(), emission()]
            .prop_map(Op::Replace),
        3 => replacement().prop_map(Op::Replace),
        2 => Just(Op::Delete),
        2 => (key(), replacement()).prop_map(|(k, v)| Op::Insert(k, v)),
    ];
    (prop::collection::vec(any::<Index>(), 0..7), op).prop_map(|(path, op)| Mutation { path, op })
}

fn children(v: &Value) -> usize {
    match v {
        Value::Array(a) => a.len(),
        Value::Object(o) => o.len(),
        _ => 0,
    }
}

fn child(v: &mut Value, i: usize) -> &mut Value {
    match v {
        Value::Array(a) => &mut a[i],
        Value::Object(o) => o.values_mut().nth(i).expect("index < len"),
        _ => unreachable!("leaves have no children"),
    }
}

/// Walk down `path` (each step picks a child) while there are children, then apply `op`
/// there; Delete removes the last child reached from its parent.
fn mutate(v: &mut Value, path: &[Index], op: &Op) {
    if let Some((step, rest)) = path.split_first() {
        let len = children(v);
        if len > 0 {
            let i = step.index(len);
            let last = rest.is_empty() || children(child(v, i)) == 0;
            if last && matches!(op, Op::Delete) {
                match v {
                    Value::Array(a) => {
                        a.remove(i);
                    }
                    Value::Object(o) => {
                        let k = o.keys().nth(i).expect("index < len").clone();
                        o.remove(&k);
                    }
                    _ => unreachable!(),
                }
                return;
            }
            return mutate(child(v, i), rest, op);
        }
    }
    match (op, v) {
        (Op::Replace(x), v) => *v = x.clone(),
        (Op::Insert(k, x), Value::Object(o)) => {
            o.insert(k.clone(), x.clone());
        }
        (Op::Insert(k, x), Value::Array(a)) => {
            let at = k.len().min(a.len());
            a.insert(at, x.clone());
        }
        (Op::Insert(_, x), v) => *v = x.clone(),
        (Op::Delete, v) => *v = Value::Null,
    }
}

/// The text of a value, compact or pretty.
fn text(v: &Value, pretty: bool) -> String {
    if pretty {
        serde_json::to_string_pretty(v).expect("values serialize")
    } else {
        serde_json::to_string(v).expect("values serialize")
    }
}

/// JSON-ish token soup: gets past the first byte of the JSON parser more often than
/// arbitrary text.
fn token_soup() -> impl Strategy<Value = String> {
    let token = prop_oneof![
        4 => prop::sample::select(vec![
            "{", "}", "[", "]", ",", ":", "\"", "\"camera\"", "\"type\"", "\"sphere\"", "null",
            "true", "-", "0", "1e999", "-1e999", "1e-999", "18446744073709551616", "NaN",
            "Infinity", "1.5", "\\u0000", "\\ud800", " ", "\n", "/*", "\u{feff}",
        ]).prop_map(String::from),
        1 => word().prop_map(|w| format!("\"{w}\"")),
        1 => ".{0,4}",
    ];
    prop::collection::vec(token, 0..64).prop_map(|t| t.concat())
}

/// A valid scene's text with a few bytes changed.
fn byte_edits() -> impl Strategy<Value = String> {
    (
        any::<bool>(),
        prop::collection::vec((any::<Index>(), any::<u8>(), 0u8..3), 1..6),
    )
        .prop_map(|(cornell, edits)| {
            let mut b = if cornell { CORNELL } else { GLASS_ORANGE }
                .as_bytes()
                .to_vec();
            for (at, byte, kind) in edits {
                let i = at.index(b.len());
                match kind {
                    0 => b[i] = byte,
                    1 => {
                        b.remove(i);
                    }
                    _ => b.insert(i, byte),
                }
            }
            String::from_utf8_lossy(&b).into_owned()
        })
}

/// (a) Arbitrary text: unicode strings, bytes (lossy UTF-8), token soup, byte edits of a
/// valid scene.
fn any_text() -> impl Strategy<Value = String> {
    prop_oneof![
        ".*",
        prop::collection::vec(any::<u8>(), 0..256)
            .prop_map(|b| String::from_utf8_lossy(&b).into_owned()),
        token_soup(),
        byte_edits(),
    ]
}

/// (b) Arbitrary JSON values of depth at most 4, values shaped like a scene, and well-formed
/// scenes with extreme numbers.
fn any_json() -> impl Strategy<Value = Value> {
    prop_oneof![1 => value(4), 2 => scene_like(), 3 => extreme_scene()]
}

/// (c) A valid scene with 1-4 nodes replaced, deleted or inserted at random paths.
fn mutated_scene() -> impl Strategy<Value = Value> {
    (any::<bool>(), prop::collection::vec(mutation(), 1..5)).prop_map(|(cornell, mutations)| {
        let base = if cornell { CORNELL } else { GLASS_ORANGE };
        let mut v: Value = serde_json::from_str(base).expect("built-in scene is JSON");
        for m in &mutations {
            mutate(&mut v, &m.path, &m.op);
        }
        v
    })
}

// ----- properties -----

proptest! {
    #![proptest_config(common::proptest_config(4096))]

    /// (a) Whatever the text, parsing returns (see [`parse_and_render`] for the checks).
    #[test]
    fn arbitrary_text_never_panics(t in any_text()) {
        parse_and_render(&t)?;
    }

    /// (b) Whatever the JSON value, parsing its text, or the value itself as the server
    /// does, returns.
    #[test]
    fn arbitrary_json_never_panics(v in any_json(), pretty in any::<bool>()) {
        parse_and_render(&text(&v, pretty))?;
        if let Err(e) = SceneDesc::from_value(v, None) {
            check_error(&e)?;
        }
    }

    /// (c) Whatever the damage to a valid scene, parsing returns.
    #[test]
    fn mutated_scenes_never_panic(v in mutated_scene()) {
        parse_and_render(&text(&v, false))?;
    }

    /// Every error is one line, whichever of the three kinds of input caused it.
    #[test]
    fn errors_are_one_line(
        t in prop_oneof![
            any_text(),
            any_json().prop_map(|v| text(&v, false)),
            mutated_scene().prop_map(|v| text(&v, false)),
        ]
    ) {
        if let Parsed::Rejected(e) = parse_and_render(&t)? {
            check_one_line(&e)?;
        }
    }

    /// Every accepted scene passes [`check_scene`] (arbitrary text is left out: it is
    /// hardly ever a scene).
    #[test]
    fn accepted_scenes_are_sane(v in prop_oneof![any_json(), mutated_scene()]) {
        if let Parsed::Accepted(b) = parse_and_render(&text(&v, false))? {
            check_scene(&b.0, &b.1)?;
        }
    }
}

/// The two base scenes parse and render (so the mutation test starts from valid input).
#[test]
fn base_scenes_pass_the_checks() {
    for t in [CORNELL, GLASS_ORANGE] {
        match parse_and_render(t).expect("base scene passes the checks") {
            Parsed::Accepted(b) => check_scene(&b.0, &b.1).expect("base scene is sane"),
            Parsed::Rejected(e) => panic!("base scene rejected: {e}"),
        }
    }
}

/// Found by `errors_are_one_line`: names from the scene are echoed verbatim in errors, line
/// breaks included: a key the format does not know (serde's "unknown field" message, and the
/// error's path), a `type` tag, a material's name (in the path of an error inside it, and in
/// the list of defined names), and an object's material.
#[test]
fn errors_quoting_names_with_line_breaks_are_one_line() {
    let scene = |materials: &str, objects: &str| {
        format!(
            r#"{{"camera": {{"position": [0, 0, 5], "look_at": [0, 0, 0], "up": [0, 1, 0],
                "fov": 40, "width": 8, "height": 8}},
              "materials": {materials}, "objects": {objects}, "lights": []}}"#
        )
    };
    let inputs = [
        r#"{"\n": 0}"#.to_string(),
        scene(r#"{"m": {"type": "a\nb"}}"#, "[]"),
        scene(r#"{"a\nb": {"type": "diffuse"}}"#, "[]"),
        scene(
            r#"{"a\nb": {"type": "diffuse", "albedo": [1, 1, 1]}}"#,
            r#"[{"type": "sphere", "material": "c", "center": [0, 0, 0], "radius": 1}]"#,
        ),
        scene(
            r#"{"m": {"type": "diffuse", "albedo": [1, 1, 1]}}"#,
            r#"[{"type": "sphere", "material": "c\nd", "center": [0, 0, 0], "radius": 1}]"#,
        ),
    ];
    let bad: Vec<String> = inputs
        .iter()
        .map(|t| Scene::parse(t, None).err().expect("an error").to_string())
        .filter(|line| line.contains(['\n', '\r']))
        .collect();
    assert!(bad.is_empty(), "errors that are not one line: {bad:#?}");
}

/// Found by `accepted_scenes_are_sane`: the engine's f32 frame is centred on the bounds of
/// the objects and the lights, so a distant light moves its origin far enough (here 5e8,
/// where f32 steps are 32) that the camera's position and look_at, 4 apart, round to the
/// same point; the camera's forward is 0/0 and every ray NaN (the image comes out black).
/// The loader's check that look_at differs from the position is relative to the camera's
/// own coordinates. A distant object does the same.
#[test]
fn a_distant_light_leaves_the_camera_defined() {
    let text = r#"{"camera": {"position": [0, 0, 4], "look_at": [0, 0, 0], "up": [0, 1, 0],
            "fov": 40, "width": 8, "height": 8},
        "materials": {"m": {"type": "diffuse", "albedo": [0.5, 0.5, 0.5]}},
        "objects": [{"type": "sphere", "material": "m", "center": [0, 0, 0], "radius": 1}],
        "lights": [{"type": "point", "position": [0, 0, 1e9], "power": [1e15, 1e15, 1e15]}]}"#;
    let scene = Scene::parse(text, None).expect("the loader accepts the scene");
    let d = scene.camera.ray(4.0, 4.0).d;
    assert!(d.is_finite(), "camera ray direction {d:?}");
    // The same light at 1e4 with its power scaled by (1e4 / 1e9)^2 gives the same image (to
    // 1e-4 in the light's direction): a distant light must not blur the geometry.
    let params = RenderSpec {
        width: Some(8),
        height: Some(8),
        ..RenderSpec::raytrace(4)
    };
    let near = text
        .replace("[0, 0, 1e9]", "[0, 0, 1e4]")
        .replace("1e15, 1e15, 1e15", "1e5, 1e5, 1e5");
    let near = Scene::parse(&near, None).unwrap();
    let a = render(&scene, &params, &Control::none()).unwrap().image;
    let b = render(&near, &params, &Control::none()).unwrap().image;
    let (ma, mb) = (a.mean_rgb(0, 0, 8, 8)[0], b.mean_rgb(0, 0, 8, 8)[0]);
    assert!(mb > 0.0 && (ma / mb - 1.0).abs() < 1e-3, "{ma} vs {mb}");
    for (pa, pb) in a.pixels.iter().zip(&b.pixels) {
        assert!(
            (pa[0] - pb[0]).abs() <= 1e-3 * pb[0].max(1e-3 * mb as f32),
            "{pa:?} vs {pb:?}"
        );
    }
}
