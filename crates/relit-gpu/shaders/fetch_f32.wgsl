// f32 storage: one value per pixel and plane.
@group(0) @binding(3) var<storage, read> planes: array<f32>;

fn fetch(plane: u32, p: u32) -> f32 {
    return planes[plane * span.a.y + p];
}
