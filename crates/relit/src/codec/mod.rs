//! Files that hold relightable images. OpenEXR ([`exr`]) is the native format; its
//! maps are stored in a [`crate::storage::Precision`] (f32 or f16).

pub mod exr;
