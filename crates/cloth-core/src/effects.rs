//! Effects are data: a scene names the physical effects it simulates.
//!
//! An effect a scene leaves out costs nothing: no springs are generated for an
//! absent spring kind, no buffer space is reserved for absent colliders, and the GPU
//! backends compile the corresponding shader code out (WGSL `override` constants,
//! Vulkan specialization constants) using [`EffectSet::shader_constants`].

use serde::{Deserialize, Serialize};

/// One physical effect of the force model.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum Effect {
    /// Weight `F_g = m g`.
    Gravity,
    /// Hooke springs between 4-neighbours (stretch resistance).
    StructuralSprings,
    /// Hooke springs along the cell diagonals (shear resistance).
    ShearSprings,
    /// Hooke springs between vertices two apart (bending resistance).
    BendSprings,
    /// Damping along each spring's extension rate, `F_d = -c_d v_s`.
    SpringDamping,
    /// Penalty contact with the colliders, `F_c = k_c d` (read as `SphereContact` too).
    #[serde(alias = "SphereContact")]
    Contact,
    /// Friction between the colliders and the cloth (needs `Contact`).
    Friction,
    /// Linear air drag `F = -m γ v` (an addition to the mass-spring model; helps a drape settle).
    AirDrag,
    /// Wind: air moving at `scene.wind` (uniform or gusting) pushes on the cloth along its normal.
    Wind,
    /// The pins follow `cloth.pin_motion` (moving attachments) instead of staying put.
    MovingPins,
    /// The colliders follow their `motion` instead of staying put (read as `MovingSpheres` too).
    #[serde(alias = "MovingSpheres")]
    MovingColliders,
    /// Cloth vertices closer than the thickness push each other apart (`scene.self_collision`,
    /// see [`crate::self_collision`]).
    SelfCollision,
}

impl Effect {
    /// Every effect, in a stable order (the order of [`EffectSet::shader_constants`]).
    pub const ALL: [Effect; 12] = [
        Effect::Gravity,
        Effect::StructuralSprings,
        Effect::ShearSprings,
        Effect::BendSprings,
        Effect::SpringDamping,
        Effect::Contact,
        Effect::Friction,
        Effect::AirDrag,
        Effect::Wind,
        Effect::MovingPins,
        Effect::MovingColliders,
        Effect::SelfCollision,
    ];

    /// Name of the boolean shader constant that compiles this effect in or out
    /// (the same name in WGSL `override` declarations and GLSL specialization constants).
    pub fn shader_constant_name(self) -> &'static str {
        match self {
            Effect::Gravity => "EFFECT_GRAVITY",
            Effect::StructuralSprings => "EFFECT_STRUCTURAL",
            Effect::ShearSprings => "EFFECT_SHEAR",
            Effect::BendSprings => "EFFECT_BEND",
            Effect::SpringDamping => "EFFECT_SPRING_DAMPING",
            Effect::Contact => "EFFECT_CONTACT",
            Effect::Friction => "EFFECT_FRICTION",
            Effect::AirDrag => "EFFECT_AIR_DRAG",
            Effect::Wind => "EFFECT_WIND",
            Effect::MovingPins => "EFFECT_MOVING_PINS",
            Effect::MovingColliders => "EFFECT_MOVING_COLLIDERS",
            Effect::SelfCollision => "EFFECT_SELF_COLLISION",
        }
    }

    fn bit(self) -> u32 {
        1 << (self as u32)
    }
}

/// The set of effects a scene simulates. Serialised in RON as a list of names,
/// e.g. `effects: [Gravity, StructuralSprings, ShearSprings]`.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(try_from = "Vec<Effect>", into = "Vec<Effect>")]
pub struct EffectSet {
    bits: u32,
}

impl EffectSet {
    /// No effect at all: vertices keep their velocity forever.
    pub const fn empty() -> Self {
        Self { bits: 0 }
    }

    /// The mass-spring model's effects: gravity, the three spring kinds with damping, contact
    /// and friction (no air drag).
    pub fn mass_spring() -> Self {
        Self::from_iter([
            Effect::Gravity,
            Effect::StructuralSprings,
            Effect::ShearSprings,
            Effect::BendSprings,
            Effect::SpringDamping,
            Effect::Contact,
            Effect::Friction,
        ])
    }

    /// Whether `effect` is simulated.
    pub fn contains(self, effect: Effect) -> bool {
        self.bits & effect.bit() != 0
    }

    /// Adds or removes one effect.
    pub fn set(&mut self, effect: Effect, on: bool) {
        if on {
            self.bits |= effect.bit();
        } else {
            self.bits &= !effect.bit();
        }
    }

    /// Returns a copy with `effect` added.
    pub fn with(mut self, effect: Effect) -> Self {
        self.set(effect, true);
        self
    }

    /// Returns a copy with `effect` removed.
    pub fn without(mut self, effect: Effect) -> Self {
        self.set(effect, false);
        self
    }

    /// The effects present, in [`Effect::ALL`] order.
    pub fn iter(self) -> impl Iterator<Item = Effect> {
        Effect::ALL.into_iter().filter(move |e| self.contains(*e))
    }

    /// Bit mask of the effects (bit `i` is `Effect::ALL[i]`); the GPU parameter block carries it
    /// for diagnostics.
    pub fn bits(self) -> u32 {
        self.bits
    }

    /// `(constant name, 1.0 or 0.0)` for every effect: the values a backend passes as
    /// WGSL override constants or Vulkan specialization constants so that absent effects are
    /// compiled out of the pipeline.
    pub fn shader_constants(self) -> Vec<(&'static str, bool)> {
        Effect::ALL.into_iter().map(|e| (e.shader_constant_name(), self.contains(e))).collect()
    }
}

impl Default for EffectSet {
    fn default() -> Self {
        Self::mass_spring()
    }
}

impl FromIterator<Effect> for EffectSet {
    fn from_iter<I: IntoIterator<Item = Effect>>(iter: I) -> Self {
        let mut set = Self::empty();
        for e in iter {
            set.set(e, true);
        }
        set
    }
}

impl TryFrom<Vec<Effect>> for EffectSet {
    type Error = String;

    /// The set of a scene's list; an effect listed twice is an error (it is one effect, and a
    /// second mention is more likely a typo for another).
    fn try_from(v: Vec<Effect>) -> Result<Self, String> {
        let mut set = Self::empty();
        for e in v {
            if set.contains(e) {
                return Err(format!("the effect {e:?} is listed twice: list each effect once"));
            }
            set.set(e, true);
        }
        Ok(set)
    }
}

impl From<EffectSet> for Vec<Effect> {
    fn from(s: EffectSet) -> Self {
        s.iter().collect()
    }
}

impl std::fmt::Debug for EffectSet {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_set().entries(self.iter()).finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_through_ron_as_a_list() {
        let set = EffectSet::empty().with(Effect::Gravity).with(Effect::BendSprings);
        let text = ron::to_string(&set).unwrap();
        assert_eq!(text, "[Gravity,BendSprings]");
        let back: EffectSet = ron::from_str(&text).unwrap();
        assert_eq!(back, set);
    }

    #[test]
    fn shader_constants_name_every_effect_once() {
        let consts = EffectSet::mass_spring().shader_constants();
        assert_eq!(consts.len(), Effect::ALL.len());
        assert!(consts.contains(&("EFFECT_FRICTION", true)));
        assert!(consts.contains(&("EFFECT_AIR_DRAG", false)));
    }
}
