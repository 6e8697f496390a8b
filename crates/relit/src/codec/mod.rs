//! Files that hold relightable images. OpenEXR ([`exr`]) is the native format.

pub mod exr;

/// Sample precision of stored maps.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Storage {
    /// 16-bit IEEE half floats (the default: half the size, ~3 significant digits).
    #[default]
    Half,
    /// 32-bit floats (exact).
    Float,
}

impl Storage {
    pub fn bytes_per_sample(self) -> usize {
        match self {
            Storage::Half => 2,
            Storage::Float => 4,
        }
    }
    pub fn name(self) -> &'static str {
        match self {
            Storage::Half => "half",
            Storage::Float => "float",
        }
    }
    /// Round `v` to what this storage keeps.
    pub fn quantize(self, v: f32) -> f32 {
        match self {
            Storage::Half => half::f16::from_f32(v).to_f32(),
            Storage::Float => v,
        }
    }
}
