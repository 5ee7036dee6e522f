//! What `umbra bench shadows` measures: the methods, and for each the points of its sweep.
//!
//! A sweep *axis* is `KEY=V1,V2,...` with a `ShadowChoice` parameter key (`map.resolution`,
//! `traced.spp`, ...); keys joined by `+` take each value together
//! (`map.constant_bias+map.slope_bias=0,1,2,4`). An axis belongs to the method its keys'
//! technique names (`map.*` to `map`, `traced.*` to `traced`, ...), and axes are swept one at a
//! time, each from the method's defaults: a method with axes of 5 and 4 values has at most 9
//! points, not 20. A point equal to one already listed (an axis value that is the default) is
//! measured once, and is on every axis that names it.

use crate::config::{ShadowChoice, ShadowMethod};

/// One method as `--methods` names it: the method and the softness its id implies.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MethodSpec {
    /// The id as results show it: `traced`, `traced-soft`, `traced-denoised`, `map`, ...
    pub id: String,
    pub method: ShadowMethod,
    /// `Some(true)` for `traced-soft` and `traced-denoised`; `None` leaves softness to each
    /// light's size.
    pub soft: Option<bool>,
    /// Parameters the id sets on every light before `--param` (`DENOISED_PARAMS`).
    pub fixed: Vec<(&'static str, &'static str)>,
}

/// The bench's id for soft traced shadows through the denoiser (`traced.denoise`): one ray per
/// pixel by default, swept over `DENOISED_SPP`; not a `--shadows` id (there it is `traced-soft`
/// with `--param traced.denoise=true`).
pub const DENOISED: &str = "traced-denoised";

/// What `traced-denoised` sets on top of `traced-soft`.
pub const DENOISED_PARAMS: &[(&str, &str)] = &[("traced.denoise", "true"), ("traced.spp", "1")];

/// `traced-denoised`'s default sweep: rays per pixel, then the spatial filter alone (no history).
const DENOISED_SPP: &[&str] = &["1", "2", "4"];
const DENOISED_SPATIAL_ONLY: &[&str] = &["0"];

impl MethodSpec {
    /// The axes swept when `--sweep` is not given, in a scene where some light has a size
    /// (`soft_lights`): the technique's full sweep, or with `quick` a tiny one.
    pub fn default_axes(&self, quick: bool, soft_lights: bool) -> Vec<Axis> {
        if self.id != DENOISED {
            return default_axes(self.method, quick, soft_lights);
        }
        let axis = |key: &str, values: &[&str]| Axis {
            keys: vec![key.to_string()],
            values: values.iter().map(|v| v.to_string()).collect(),
        };
        match (quick, soft_lights) {
            (false, true) => vec![axis("traced.spp", DENOISED_SPP), axis("traced.history", DENOISED_SPATIAL_ONLY)],
            _ => Vec::new(),
        }
    }
}

/// The methods measured when `--methods` is not given: every technique of the registry.
pub fn default_methods() -> String {
    ShadowMethod::TECHNIQUES.iter().map(|m| m.id()).collect::<Vec<_>>().join(",")
}

/// Parses `--methods`: method ids (and their aliases) separated by commas, each once.
pub fn parse_methods(text: &str) -> Result<Vec<MethodSpec>, String> {
    let mut out: Vec<MethodSpec> = Vec::new();
    for part in text.split(',').map(str::trim) {
        if part.is_empty() {
            return Err(format!("--methods {text:?}: an empty method id"));
        }
        let (id, method, soft, fixed) = if part == DENOISED {
            (DENOISED.to_string(), ShadowMethod::Traced, Some(true), DENOISED_PARAMS.to_vec())
        } else {
            let (method, soft) =
                ShadowMethod::parse(part).map_err(|e| format!("{e}; the bench also has {DENOISED}"))?;
            let id = match soft {
                Some(true) => "traced-soft".to_string(),
                _ => method.id().to_string(),
            };
            (id, method, soft, Vec::new())
        };
        if out.iter().any(|m| m.id == id) {
            return Err(format!("--methods {text:?}: {id} is named twice"));
        }
        out.push(MethodSpec { id, method, soft, fixed });
    }
    Ok(out)
}

/// One sweep axis: keys set together to each value in turn.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Axis {
    pub keys: Vec<String>,
    pub values: Vec<String>,
}

impl Axis {
    /// `map.resolution`, or `map.constant_bias+map.slope_bias`.
    pub fn name(&self) -> String {
        self.keys.join("+")
    }

    /// The technique the keys name (`map` for `map.resolution`).
    pub fn technique(&self) -> &str {
        self.keys[0].split_once('.').map_or(self.keys[0].as_str(), |(t, _)| t)
    }

    /// Whether the axis applies to `method`.
    pub fn applies_to(&self, method: ShadowMethod) -> bool {
        self.technique() == method.id()
    }

    /// The assignments of value `i`: `(key, value)` for each key.
    pub fn assignments(&self, i: usize) -> Vec<(String, String)> {
        self.keys.iter().map(|k| (k.clone(), self.values[i].clone())).collect()
    }
}

/// Parses `--sweep KEY=V1,V2,...` (keys joined by `+` move together), checking every key and
/// value against `ShadowChoice::set`.
pub fn parse_axis(text: &str) -> Result<Axis, String> {
    let (keys, values) = text
        .split_once('=')
        .ok_or_else(|| format!("--sweep {text:?}: write KEY=V1,V2,..., e.g. map.resolution=512,2048"))?;
    let keys: Vec<String> = keys.split('+').map(|k| k.trim().to_string()).collect();
    let values: Vec<String> = values.split(',').map(|v| v.trim().to_string()).collect();
    if keys.iter().any(String::is_empty) {
        return Err(format!("--sweep {text:?}: an empty key"));
    }
    if values.iter().any(String::is_empty) {
        return Err(format!("--sweep {text:?}: an empty value"));
    }
    let technique = |k: &str| k.split_once('.').map(|(t, _)| t.to_string());
    let first = technique(&keys[0]);
    if keys.iter().any(|k| technique(k) != first) {
        return Err(format!("--sweep {text:?}: keys moved together must belong to one technique"));
    }
    for key in &keys {
        for value in &values {
            ShadowChoice::default().set(key, value).map_err(|e| format!("--sweep {text}: {e}"))?;
        }
    }
    for (i, v) in values.iter().enumerate() {
        if values[..i].contains(v) {
            return Err(format!("--sweep {text:?}: {v} is listed twice"));
        }
    }
    Ok(Axis { keys, values })
}

/// The axes swept when `--sweep` is not given, for `method` in a scene where some light has a
/// size (`soft_lights`): the full sweep, or with `quick` a tiny one.
pub fn default_axes(method: ShadowMethod, quick: bool, soft_lights: bool) -> Vec<Axis> {
    // `auto` is measured by the methods it picks from (the bench rings its choice); `none` has
    // nothing to sweep.
    let Some(technique) = crate::shadows::technique(method) else {
        return Vec::new();
    };
    let text = |list: &[&str]| list.iter().map(|k| k.to_string()).collect();
    technique
        .sweep(quick, soft_lights)
        .into_iter()
        .map(|(keys, values)| Axis { keys: text(keys), values: text(values) })
        .collect()
}

/// One point of a method's sweep: the assignments made on top of each light's base choice, and
/// the axes (name, value) it lies on (empty for the method's defaults alone).
#[derive(Clone, Debug, PartialEq)]
pub struct Point {
    pub assignments: Vec<(String, String)>,
    pub on_axes: Vec<(String, String)>,
    /// Each light's choice at this point.
    pub choices: Vec<ShadowChoice>,
}

impl Point {
    /// `map.resolution=512`, several joined by `; `, or `default`.
    pub fn label(&self) -> String {
        if self.on_axes.is_empty() {
            return "default".into();
        }
        self.on_axes.iter().map(|(a, v)| format!("{a}={v}")).collect::<Vec<_>>().join("; ")
    }
}

/// Each light's choice for `method`: the scene's own choice (its parameters), the method and
/// its softness, then `params` (`KEY=VALUE` for every light, the bench's `--param`).
pub fn base_choices(
    scene_choices: &[ShadowChoice],
    lights: usize,
    method: &MethodSpec,
    params: &[(String, String)],
) -> Result<Vec<ShadowChoice>, String> {
    (0..lights)
        .map(|i| {
            let mut c = scene_choices.get(i).copied().unwrap_or_default();
            c.method = method.method;
            if method.soft.is_some() {
                c.traced.soft = method.soft;
            }
            for (k, v) in &method.fixed {
                c.set(k, v).map_err(|e| format!("{}: {k}={v}: {e}", method.id))?;
            }
            for (k, v) in params {
                c.set(k, v).map_err(|e| format!("--param {k}={v}: {e}"))?;
            }
            Ok(c)
        })
        .collect()
}

/// The points of `method`'s sweep over `axes` (those that apply to it), from `base`: the
/// defaults first when no axis applies, else each axis's values in turn, points with equal
/// choices merged.
pub fn points(method: ShadowMethod, base: &[ShadowChoice], axes: &[Axis]) -> Result<Vec<Point>, String> {
    let mut out: Vec<Point> = Vec::new();
    let applying: Vec<&Axis> = axes.iter().filter(|a| a.applies_to(method)).collect();
    if applying.is_empty() {
        out.push(Point { assignments: Vec::new(), on_axes: Vec::new(), choices: base.to_vec() });
        return Ok(out);
    }
    for axis in applying {
        for (i, value) in axis.values.iter().enumerate() {
            let assignments = axis.assignments(i);
            let mut choices = base.to_vec();
            for c in &mut choices {
                for (k, v) in &assignments {
                    c.set(k, v)?;
                }
            }
            let on = (axis.name(), value.clone());
            match out.iter_mut().find(|p| p.choices == choices) {
                Some(p) => p.on_axes.push(on),
                None => out.push(Point { assignments, on_axes: vec![on], choices }),
            }
        }
    }
    Ok(out)
}
