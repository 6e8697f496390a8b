use super::*;
use crate::image::ImageRgb;
use std::sync::Arc;

#[test]
fn rig_json_round_trips_with_defaults() {
    let text = r#"{"lights":[
        {"type":"directional","direction":[0,0,1]},
        {"type":"point","position":[0,1,-2],"attenuation":{"inverse_distance":2.0}},
        {"type":"spot","position":[0,2,-3],"direction":[0,-1,0],"cone_deg":30},
        {"type":"projector","position":[0,1,0],"direction":[0,0,-1],"fov_deg":40,"slide":"s.png"},
        {"type":"area","shape":{"disk":{"center":[0,3,-3],"normal":[0,-1,0],"radius":0.5}},"two_sided":true}
    ]}"#;
    let rig = match RigFile::parse(text, "t").unwrap() {
        RigFile::Rig(r) => r,
        _ => panic!("a plain rig"),
    };
    assert_eq!(rig.lights.len(), 5);
    assert_eq!(rig.lights[0].rgb(), [1.0; 3]);
    let back: LightRig = serde_json::from_str(&rig.to_json()).unwrap();
    assert_eq!(back, rig);
    assert!(RigFile::parse(r#"{"lights":[{"type":"laser","direction":[0,0,1]}]}"#, "t").is_err());
    assert!(RigFile::parse(
        r#"{"lights":[{"type":"spot","position":[0,0,0],"direction":[0,0,1],"cone_deg":200}]}"#,
        "t"
    )
    .unwrap_err()
    .to_string()
    .contains("lights[0] (spot)"));
}

#[test]
fn flag_specs() {
    assert_eq!(
        Light::parse_spec("dir:0,0,2").unwrap(),
        Light::directional([0.0, 0.0, 2.0], [1.0; 3])
    );
    assert_eq!(
        Light::parse_spec("point:1,2,3").unwrap(),
        Light::point([1.0, 2.0, 3.0], [1.0; 3])
    );
    assert!(matches!(
        Light::parse_spec("spot:0,2,0/0,-1,0/30").unwrap(),
        Light::Spot(_)
    ));
    for bad in [
        "dir:0,0",
        "dir:0,0,0",
        "dir:0,nan,1",
        "sun:0,0,1",
        "0,0,1",
        "spot:0,2,0/0,-1,0",
        "spot:0,2,0/0,0,0/30",
    ] {
        assert!(Light::parse_spec(bad).is_err(), "{bad}");
    }
}

#[test]
fn point_and_spot_falloff() {
    let p = PointLight {
        position: Vec3::new(0.0, 2.0, 0.0),
        color: [1.0; 3],
        intensity: 1.0,
        attenuation: Attenuation::default(),
    };
    let mut got = Vec::new();
    p.illuminate(Vec3::new(0.0, 0.0, 0.0), [1.0; 3], &mut |l, s| {
        got.push((l, s))
    });
    assert_eq!(got.len(), 1);
    assert!(
        (got[0].0 - Vec3::new(0.0, 1.0, 0.0)).length() < 1e-12,
        "L points toward the light"
    );
    assert!(
        (got[0].1[0] - 0.25).abs() < 1e-12,
        "inverse square at distance 2"
    );
    assert!((Attenuation::InverseDistance(3.0).factor(2.0) - 1.5).abs() < 1e-12);

    let spot = SpotLight {
        position: Vec3::new(0.0, 0.0, 0.0),
        direction: Vec3::new(0.0, 0.0, -1.0),
        cone_deg: 30.0,
        softness_deg: 10.0,
        color: [1.0; 3],
        intensity: 1.0,
        attenuation: Attenuation::None,
    };
    let at = |deg: f64| spot.cone_factor(deg.to_radians().cos());
    assert_eq!(at(0.0), 1.0);
    assert_eq!(at(19.9), 1.0);
    assert_eq!(at(30.1), 0.0);
    assert!(at(22.0) > at(25.0) && at(25.0) > at(28.0) && at(28.0) > 0.0);
}

#[test]
fn disk_light_matches_the_closed_form_irradiance() {
    // On the axis of a disk of radius R at height h, irradiance on a receiver facing it
    // is π·L_e·R²/(h² + R²) (the physics check of pbrt's light tests).
    let (r, h) = (0.8, 1.5);
    let light = AreaLight {
        shape: AreaShape::Disk {
            center: Vec3::new(0.0, h, 0.0),
            normal: Vec3::new(0.0, -1.0, 0.0),
            radius: r,
        },
        color: [1.0; 3],
        intensity: 2.0,
        two_sided: false,
        samples: 4096,
    };
    let mut e = 0.0;
    light.illuminate(Vec3::new(0.0, 0.0, 0.0), 7, [2.0; 3], &mut |l, s| {
        e += s[0] * l.y
    });
    let want = std::f64::consts::PI * 2.0 * r * r / (h * h + r * r);
    assert!((e - want).abs() / want < 5e-3, "{e} vs {want}");
    // Behind a one-sided emitter there is no light.
    let mut behind = 0.0;
    light.illuminate(Vec3::new(0.0, 3.0, 0.0), 7, [2.0; 3], &mut |_, s| {
        behind += s[0]
    });
    assert_eq!(behind, 0.0);
}

#[test]
fn projector_samples_its_slide_inside_the_frustum() {
    let mut slide = ImageRgb::new(3, 3);
    slide.data[3 * 4] = 1.0; // centre pixel red
    slide.data[1] = 1.0; // top-left pixel green
    let proj = ProjectorLight {
        position: Vec3::new(0.0, 0.0, 0.0),
        direction: Vec3::new(0.0, 0.0, -1.0),
        up: Vec3::new(0.0, 1.0, 0.0),
        fov_deg: 90.0,
        slide: String::new(),
        color: [1.0; 3],
        intensity: 1.0,
        attenuation: Attenuation::None,
    }
    .with_slide(Arc::new(slide));
    let centre = proj.slide_color(Vec3::new(0.0, 0.0, -2.0)).unwrap();
    assert!((centre[0] - 1.0).abs() < 1e-12 && centre[1].abs() < 1e-12);
    // Upper left of the frustum (x < 0, y > 0) shows the slide's top-left pixel.
    let corner = proj.slide_color(Vec3::new(-1.9, 1.9, -2.0)).unwrap();
    assert!(corner[1] > 0.9, "{corner:?}");
    assert!(
        proj.slide_color(Vec3::new(0.0, 0.0, 2.0)).is_none(),
        "behind the projector"
    );
    assert!(
        proj.slide_color(Vec3::new(5.0, 0.0, -2.0)).is_none(),
        "outside the frustum"
    );
}

#[test]
fn animations_interpolate_and_validate() {
    let text = r#"{"keyframes":[
        {"time":0,"lights":[{"type":"point","position":[-2,1,0],"color":[1,0,0]}]},
        {"time":2,"lights":[{"type":"point","position":[2,1,0],"color":[0,0,1]}]}]}"#;
    let RigFile::Animation(anim) = RigFile::parse(text, "t").unwrap() else {
        panic!("an animation")
    };
    let mid = anim.rig_at(1.0).unwrap();
    let Light::Point(p) = &mid.lights[0] else {
        panic!()
    };
    assert!((p.position - Vec3::new(0.0, 1.0, 0.0)).length() < 1e-12);
    assert_eq!(p.color, [0.5, 0.0, 0.5]);
    let frames = anim.frames(5).unwrap();
    assert_eq!(frames.len(), 5);
    assert_eq!(frames[4], anim.rig_at(2.0).unwrap());
    let mismatched = r#"{"keyframes":[{"time":0,"lights":[{"type":"point","position":[0,0,0]}]},
                                      {"time":1,"lights":[{"type":"directional","direction":[0,0,1]}]}]}"#;
    assert!(RigFile::parse(mismatched, "t")
        .unwrap_err()
        .to_string()
        .contains("same lights"));
    let backwards = r#"{"keyframes":[{"time":1,"lights":[]},{"time":0,"lights":[]}]}"#;
    assert!(RigFile::parse(backwards, "t").is_err());
}

#[test]
fn rig_files_name_every_slide_and_map_they_read() {
    let projector = |slide: &str| {
        format!(
            r#"{{"type":"projector","position":[0,0,2],"direction":[0,0,-1],"up":[0,1,0],"fov_deg":40,"slide":"{slide}"}}"#
        )
    };
    let text = format!(
        r#"{{"keyframes":[{{"time":0,"lights":[{},{{"type":"environment","map":"sky.hdr"}}]}},
                         {{"time":1,"lights":[{},{{"type":"environment","map":"sky.hdr"}}]}}]}}"#,
        projector("a.png"),
        projector("sub/b.png")
    );
    let files = RigFile::parse(&text, "t")
        .unwrap()
        .referenced_files(Path::new("rigs"));
    let expected: Vec<std::path::PathBuf> = ["rigs/a.png", "rigs/sky.hdr", "rigs/sub/b.png"]
        .iter()
        .map(Into::into)
        .collect();
    assert_eq!(files, expected);
    let plain = RigFile::parse(
        r#"{"lights":[{"type":"directional","direction":[0,0,1]}]}"#,
        "t",
    );
    assert!(plain.unwrap().referenced_files(Path::new(".")).is_empty());
}
