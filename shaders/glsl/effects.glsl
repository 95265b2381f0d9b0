// The specialization constants every compute kernel of the cloth shares: the effects (ids in
// cloth_core::Effect::ALL order, set from cloth_core::EffectSet::shader_constants; the driver
// removes the code behind a false constant), the collider kinds and the workgroup size (id 100).

layout(constant_id = 0) const bool EFFECT_GRAVITY = true;
layout(constant_id = 1) const bool EFFECT_STRUCTURAL = true;
layout(constant_id = 2) const bool EFFECT_SHEAR = true;
layout(constant_id = 3) const bool EFFECT_BEND = true;
layout(constant_id = 4) const bool EFFECT_SPRING_DAMPING = true;
layout(constant_id = 5) const bool EFFECT_CONTACT = true;
layout(constant_id = 6) const bool EFFECT_FRICTION = true;
layout(constant_id = 7) const bool EFFECT_AIR_DRAG = false;
layout(constant_id = 8) const bool EFFECT_WIND = false;
layout(constant_id = 9) const bool EFFECT_MOVING_PINS = false;
layout(constant_id = 10) const bool EFFECT_MOVING_COLLIDERS = false;
layout(constant_id = 11) const bool EFFECT_SELF_COLLISION = false;
// The collider kinds (ids from cloth_gpu::plan::COLLIDER_CONSTANT_IDS, in ColliderKind::ALL order):
// true when a collider of the scene has the kind.
layout(constant_id = 20) const bool COLLIDER_SPHERE = true;
layout(constant_id = 21) const bool COLLIDER_PLANE = true;
layout(constant_id = 22) const bool COLLIDER_CAPSULE = true;
layout(constant_id = 23) const bool COLLIDER_BOX = true;
layout(constant_id = 24) const bool COLLIDER_MESH = true;
// Any spring kind at all (a specialization-constant expression, so the branch on it is constant).
#define ANY_SPRINGS (EFFECT_STRUCTURAL || EFFECT_SHEAR || EFFECT_BEND)
// local_size_x is the default; local_size_x_id makes it specializable (id 100). (A kernel whose
// workgroup has another shape defines TILED_WORKGROUP first and declares its own.)
#ifndef TILED_WORKGROUP
layout(local_size_x = 256, local_size_x_id = 100) in;
#endif
