//! Captures whose photographs are TGA or BMP (public photometric-stereo sets ship TGA)
//! open like any other and decode to the same pixels as the PNG of the same picture.

use relit::capture::Capture;

#[test]
fn tga_and_bmp_captures_load_like_png() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let lights = [
        [0.0, 0.0, 1.0],
        [0.5, 0.0, 0.866],
        [0.0, 0.5, 0.866],
        [-0.5, 0.0, 0.866],
    ];
    let mut lp: [String; 3] = std::array::from_fn(|_| format!("{}\n", lights.len()));
    for (j, l) in lights.iter().enumerate() {
        let picture = image::RgbImage::from_fn(8, 6, |x, y| {
            image::Rgb([(x * 30 + j as u32 * 7) as u8, (y * 40) as u8, 90 + j as u8])
        });
        for (k, ext) in ["png", "tga", "bmp"].iter().enumerate() {
            let name = format!("light{j}.{ext}");
            picture.save(d.join(&name)).unwrap();
            lp[k].push_str(&format!("{name} {} {} {}\n", l[0], l[1], l[2]));
        }
    }
    let mut loaded = Vec::new();
    for (k, ext) in ["png", "tga", "bmp"].iter().enumerate() {
        let path = d.join(format!("{ext}.lp"));
        std::fs::write(&path, &lp[k]).unwrap();
        let capture = Capture::open(&path).unwrap();
        assert_eq!((capture.len(), capture.width, capture.height), (4, 8, 6));
        loaded.push(
            (0..4)
                .map(|j| capture.load(j).unwrap().data)
                .collect::<Vec<_>>(),
        );
    }
    assert_eq!(loaded[0], loaded[1], "TGA decodes like PNG");
    assert_eq!(loaded[0], loaded[2], "BMP decodes like PNG");
}
