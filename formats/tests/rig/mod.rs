//! Fixtures the animation-section and verification tests share: one furry triangle and a
//! two-joint skeleton whose second inverse bind moves it down one unit.

use furbake_formats::sections::skeleton::Skeleton;
use furbake_formats::sections::skin_mesh::SkinMesh;

/// The 4×4 identity, column-major.
const IDENTITY: [f32; 16] = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0];

/// One furry triangle in the z = 0 plane.
pub fn mesh() -> SkinMesh {
    SkinMesh {
        positions: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        normals: vec![[0.0, 0.0, 1.0]; 3],
        colors: vec![[1.0; 4]; 3],
        triangles: vec![[0, 1, 2]],
        fur_mask: vec![1],
        ..SkinMesh::default()
    }
}

/// `root` and its child `bone` one unit up, each bound (the bone's inverse bind moves it back).
pub fn skeleton() -> Skeleton {
    let mut shifted = IDENTITY;
    shifted[13] = -1.0;
    Skeleton {
        names: vec!["root".into(), "bone".into()],
        parents: vec![Skeleton::NO_PARENT, 0],
        translations: vec![[0.0; 3], [0.0, 1.0, 0.0]],
        rotations: vec![[0.0, 0.0, 0.0, 1.0]; 2],
        scales: vec![[1.0; 3]; 2],
        bind_joints: vec![0, 1],
        inverse_binds: vec![IDENTITY, shifted],
        skin_root: Some(0),
        nodes: vec![0, 1],
    }
}
