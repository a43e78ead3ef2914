//! Animators: a pack's own clip sampler outside any world, for a host that wants the clips'
//! joint matrices (to drive its own skeleton, or to hand them back through
//! `furbake_world_set_joint_matrices`).

use std::ffi::c_char;

use furbake_runtime::Animator;

use crate::error::{Error, FurbakeResult, guard, optional_text, out};
use crate::pack::{FurbakePack, pack_ref};
use crate::views::write_view;
use crate::world::FurbakeSkinPose;

/// A clip sampler on one pack (opaque): made by `furbake_animator_create`, freed by
/// `furbake_animator_release`.
pub struct FurbakeAnimator {
    animator: Animator,
}

pub(crate) fn skin_pose(a: &Animator) -> FurbakeSkinPose {
    FurbakeSkinPose {
        size: 0,
        vertex_count: a.positions().len() as u32,
        positions: a.positions().as_ptr().cast(),
        normals: a.normals().as_ptr().cast(),
        joint_count: a.joint_matrices().len() as u32,
        // glam's `Mat4` is 16 column-major floats.
        joint_matrices: a.joint_matrices().as_ptr().cast(),
        bind_count: a.skinning_matrices().len() as u32,
        skinning_matrices: a.skinning_matrices().as_ptr().cast(),
        morph_count: a.morph_weights().len() as u32,
        morph_weights: a.morph_weights().as_ptr(),
    }
}

/// Makes a sampler of `pack`'s clip `clip` (null: the rest pose) and stores it in
/// `*out_animator`. The pack may be released afterwards.
///
/// # Safety
/// `pack` is a live handle; `clip` is null or NUL-terminated; `out_animator` points to storage.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_animator_create(
    pack: *const FurbakePack,
    clip: *const c_char,
    out_animator: *mut *mut FurbakeAnimator,
) -> FurbakeResult {
    guard(|| {
        let pack = &pack_ref("pack", pack)?.pack;
        let clip = optional_text("clip", clip)?;
        let slot = out("out_animator", out_animator)?;
        let animator = Animator::new(pack, clip, 1.0, true, 0.0)?;
        *slot = Box::into_raw(Box::new(FurbakeAnimator { animator }));
        Ok(())
    })
}

/// Frees an animator (null is ignored).
///
/// # Safety
/// `animator` is null or a handle from this library, not used again.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_animator_release(animator: *mut FurbakeAnimator) {
    if !animator.is_null() {
        // SAFETY: a handle made by `Box::into_raw` in this module, released once.
        let _ = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| drop(unsafe { Box::from_raw(animator) })));
    }
}

/// Poses the clip at `time_s` (looped over the clip's length) and fills `*pose`: the joint
/// matrices (what `furbake_world_set_joint_matrices` takes), the skinning matrices and the
/// posed skin. The views stay valid until the animator's next call.
///
/// # Safety
/// `animator` is a live handle; `pose` points to a view whose `size` is set.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_animator_pose(
    animator: *mut FurbakeAnimator,
    time_s: f64,
    pose: *mut FurbakeSkinPose,
) -> FurbakeResult {
    guard(|| {
        // SAFETY: a non-null handle is one this library made and the caller has not released.
        let a = unsafe { animator.as_mut() }.ok_or_else(|| Error::argument("animator is a null pointer"))?;
        let invalid = |e| Error::new(FurbakeResult::InvalidArgument, format!("animator: {e}"));
        a.animator.seek(time_s as f32).map_err(invalid)?;
        a.animator.update().map_err(invalid)?;
        write_view("pose", pose, skin_pose(&a.animator))
    })
}
