//! The scene file's lights: each `[[lights]]` table checked into a `Light` or a `RectLight`,
//! and its shadow method and parameters.

use super::desc::{LightDesc, LightKind};
use super::Check;
use crate::scene::error::{short_number, SceneError};
use crate::scene::values::Xyz;
use crate::scene::{Light, RectLight};

impl Check<'_> {
    /// The light's shadow method and parameters (`shadows`, `soft` and the technique tables).
    pub(super) fn shadows(&self, path: &str, light: &LightDesc) -> Result<crate::config::ShadowChoice, SceneError> {
        use crate::config::ShadowMethod;
        let (method, soft) = match &light.shadows {
            Some(id) => ShadowMethod::parse(id).map_err(|e| self.fail(&format!("{path}.shadows"), e))?,
            None => (ShadowMethod::default(), None),
        };
        if let (Some(implied), Some(given)) = (soft, light.soft) {
            if implied != given {
                let message =
                    format!("{:?} asks for soft shadows but `soft = false`", light.shadows.as_deref().unwrap_or(""));
                return Err(self.fail(&format!("{path}.soft"), message));
            }
        }
        let mut choice = light.choice(method);
        if light.traced.is_some_and(|t| t.soft.is_some()) {
            return Err(self.fail(&format!("{path}.traced.soft"), "write `soft` on the light itself"));
        }
        choice.traced.soft = light.soft.or(soft);
        choice.check_tables().map_err(|(table, e)| self.fail(&format!("{path}.{table}"), e))?;
        Ok(choice)
    }

    /// Refuses a key the light's type does not take and a missing one it needs.
    fn light_keys(&self, path: &str, light: &LightDesc) -> Result<(), SceneError> {
        let (name, needs, optional): (&str, &[&str], &[&str]) = match light.kind {
            LightKind::Point => ("point", &["position", "intensity"], &["radius"]),
            LightKind::Directional => ("directional", &["direction", "irradiance"], &["angular_diameter_deg"]),
            LightKind::Spot => ("spot", &["position", "direction", "intensity", "inner_deg", "outer_deg"], &["radius"]),
            LightKind::Rect => ("rect", &["center", "half_edge_u", "half_edge_v", "radiance"], &["two_sided", "spp"]),
        };
        let given = [
            ("position", light.position.is_some()),
            ("direction", light.direction.is_some()),
            ("intensity", light.intensity.is_some()),
            ("irradiance", light.irradiance.is_some()),
            ("inner_deg", light.inner_deg.is_some()),
            ("outer_deg", light.outer_deg.is_some()),
            ("radius", light.radius.is_some()),
            ("angular_diameter_deg", light.angular_diameter_deg.is_some()),
            ("center", light.center.is_some()),
            ("half_edge_u", light.half_edge_u.is_some()),
            ("half_edge_v", light.half_edge_v.is_some()),
            ("radiance", light.radiance.is_some()),
            ("two_sided", light.two_sided.is_some()),
            ("spp", light.spp.is_some()),
        ];
        for (key, present) in given {
            if present && !needs.contains(&key) && !optional.contains(&key) {
                let expected = needs.join("`, `");
                let optional = optional.join("`, `");
                let message = format!("not used by a {name} light (it takes `{expected}`, optionally `{optional}`)");
                return Err(self.fail(&format!("{path}.{key}"), message));
            }
            if !present && needs.contains(&key) {
                return Err(self.fail(path, format!("a {name} light needs `{key}`")));
            }
        }
        Ok(())
    }

    /// A rect light: keys, finite values, perpendicular edges and a nonzero area (in f32).
    /// Its shadows are not a per-light technique choice, so the shadow keys are refused.
    pub(super) fn rect(&self, path: &str, light: &LightDesc) -> Result<RectLight, SceneError> {
        self.light_keys(path, light)?;
        if let Some(key) = [("keys", light.keys.is_some()), ("interpolation", light.interpolation.is_some())]
            .iter()
            .find_map(|(key, present)| present.then_some(key))
        {
            let message = "rect lights do not move: only point, spot and directional lights take keys";
            return Err(self.fail(&format!("{path}.{key}"), message));
        }
        let mut shadow_keys = vec![("shadows", light.shadows.is_some()), ("soft", light.soft.is_some())];
        shadow_keys.extend(light.tables_given());
        if let Some((key, _)) = shadow_keys.iter().find(|(_, present)| *present) {
            let message = "a rect light takes no shadow settings (its shadows are always traced)";
            return Err(self.fail(&format!("{path}.{key}"), message));
        }
        let field = |v: &Option<Xyz>| v.as_ref().map_or([0.0; 3], |v| v.0);
        let center = self.point(&format!("{path}.center"), field(&light.center))?;
        let u = self.point(&format!("{path}.half_edge_u"), field(&light.half_edge_u))?.as_vec3();
        let v = self.point(&format!("{path}.half_edge_v"), field(&light.half_edge_v))?.as_vec3();
        let radiance = self.power(&format!("{path}.radiance"), field(&light.radiance))?;
        let cross = u.cross(v);
        if !(cross.is_finite() && cross.length() > 0.0) {
            let message = "the rect has zero area (half_edge_u x half_edge_v is zero or not finite)";
            return Err(self.fail(path, message));
        }
        if u.dot(v).abs() > 1e-3 * u.length() * v.length() {
            return Err(self.fail(path, "half_edge_u and half_edge_v must be perpendicular"));
        }
        let spp = light.spp.unwrap_or(RectLight::DEFAULT_SPP);
        if spp > RectLight::MAX_SPP {
            return Err(self.fail(&format!("{path}.spp"), format!("{spp} is outside [0, {}]", RectLight::MAX_SPP)));
        }
        let two_sided = light.two_sided.unwrap_or(false);
        let rect = RectLight { center, half_edge_u: u, half_edge_v: v, radiance, two_sided, spp };
        Ok(rect)
    }

    pub(super) fn light(&self, path: &str, light: &LightDesc) -> Result<Light, SceneError> {
        self.light_keys(path, light)?;
        // Presence is checked above; these defaults are never used.
        let field = |v: &Option<Xyz>| v.as_ref().map_or([0.0; 3], |v| v.0);
        let position = || self.point(&format!("{path}.position"), field(&light.position));
        let direction = || self.direction(&format!("{path}.direction"), field(&light.direction));
        let power = |key: &str, v| self.power(&format!("{path}.{key}"), field(v));
        // Absent sizes are 0: a point or a single direction, hard shadows as before.
        let radius = || {
            let v = light.radius.unwrap_or(0.0);
            if !(v >= 0.0 && (v as f32).is_finite()) {
                let message = format!("{} must be finite and >= 0", short_number(v));
                return Err(self.fail(&format!("{path}.radius"), message));
            }
            Ok(v as f32)
        };
        Ok(match light.kind {
            LightKind::Point => Light::Point {
                position: position()?,
                intensity: power("intensity", &light.intensity)?,
                radius: radius()?,
            },
            LightKind::Directional => {
                // Below 90 degrees the cone is narrower than a hemisphere and tan(half-angle),
                // what the GPU stores, stays finite.
                let diameter = light.angular_diameter_deg.unwrap_or(0.0);
                if !(0.0..90.0).contains(&diameter) {
                    let key_path = format!("{path}.angular_diameter_deg");
                    return Err(self.fail(&key_path, format!("{} is outside [0, 90)", short_number(diameter))));
                }
                Light::Directional {
                    direction: direction()?.as_vec3(),
                    irradiance: power("irradiance", &light.irradiance)?,
                    angular_diameter_deg: diameter as f32,
                }
            }
            LightKind::Spot => {
                let inner = light.inner_deg.unwrap_or_default();
                let outer = light.outer_deg.unwrap_or_default();
                if !(0.0 <= inner && inner < outer && outer <= 90.0) {
                    let (inner, outer) = (short_number(inner), short_number(outer));
                    let message = format!("need 0 <= inner_deg < outer_deg <= 90, got {inner} and {outer}");
                    return Err(self.fail(path, message));
                }
                Light::Spot {
                    position: position()?,
                    direction: direction()?.as_vec3(),
                    intensity: power("intensity", &light.intensity)?,
                    inner_deg: inner as f32,
                    outer_deg: outer as f32,
                    radius: radius()?,
                }
            }
            LightKind::Rect => unreachable!("rect lights are checked by Check::rect"),
        })
    }
}
