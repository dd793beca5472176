//! Round trip, determinism and every kind of bad package.

use std::collections::BTreeMap;

use geo::{MultiPolygon, polygon};
use glam::Vec3;

use super::*;
use crate::blocks::UrbanBlock;
use crate::city::{BuildingId, BuildingPart, GroundClass, HeightSource, StreetClass, TriangleMesh};
use crate::ground_surfaces::GroundSurfaces;
use crate::quadtree::{Aabb, QuadNode, QuadNodeKind};
use crate::scene_geometry::SceneGeometry;

fn building(i: u32, x: f64) -> Building {
    let footprint = MultiPolygon::new(vec![polygon![
        (x: x, y: 0.0), (x: x + 8.0, y: 0.0), (x: x + 8.0, y: 6.0), (x: x, y: 6.0)
    ]]);
    let mut tags = BTreeMap::new();
    tags.insert("building".to_string(), "yes".to_string());
    Building {
        id: BuildingId(i),
        source_id: format!("way/{i}"),
        footprint: footprint.clone(),
        parts: vec![BuildingPart {
            source_id: format!("way/{i}"),
            footprint,
            base_m: 0.0,
            top_m: 12.5,
        }],
        base_m: 0.0,
        top_m: 12.5,
        height_source: HeightSource::Tagged,
        mesh: Some(Box::new(TriangleMesh {
            positions: vec![
                Vec3::new(x as f32, 0.0, 0.0),
                Vec3::new(x as f32 + 8.0, 0.0, 0.0),
                Vec3::new(x as f32 + 8.0, 0.0, 12.5),
            ],
            indices: vec![0, 1, 2],
        })),
        tags: tags.into(),
    }
}

/// A small but complete package: two buildings in one block, one quadtree leaf.
pub(crate) fn small_package() -> ScenePackage {
    let buildings = vec![building(0, 0.0), building(1, 20.0)];
    let bounds = Aabb {
        min: [0.0, 0.0, 0.0],
        max: [28.0, 6.0, 12.5],
    };
    let blocks = UrbanBlocks {
        blocks: vec![UrbanBlock {
            outline: None,
            buildings: vec![BuildingId(0), BuildingId(1)],
            bounds_min: bounds.min,
            bounds_max: bounds.max,
        }],
        block_of_building: vec![0, 0],
    };
    let quadtree = BQuadtree {
        root_min: [0.0, 0.0],
        root_max: [28.0, 6.0],
        nodes: vec![QuadNode {
            key: 1,
            kind: QuadNodeKind::Leaf {
                blocks: vec![0],
                bounds,
            },
        }],
        block_bounds: vec![bounds],
    };
    let mut counts = BTreeMap::new();
    counts.insert("blocks".to_string(), 1);
    let gpu_scene = GpuScene::build(&city_of(&buildings), None, None);
    let mut package = ScenePackage {
        frame: Frame::wgs84(-8.61, 41.15),
        buildings,
        streets: vec![Street {
            source_id: "way/9".into(),
            class: StreetClass::Residential,
            name: Some("Rua".into()),
            line: geo::LineString::from(vec![(0.0, -5.0), (30.0, -5.0)]),
            tagged_width_m: Some(8.5),
        }],
        ground_areas: vec![GroundArea {
            source_id: "way/10".into(),
            class: GroundClass::Park,
            polygon: MultiPolygon::new(vec![geo::Polygon::new(
                geo::LineString::from(vec![
                    (0.0, -20.0),
                    (30.0, -20.0),
                    (30.0, -12.0),
                    (0.0, -20.0),
                ]),
                vec![],
            )]),
        }],
        ground_surfaces: GroundSurfaces::default(),
        blocks,
        quadtree,
        occluders: None,
        cluster_tree: None,
        cluster_textures: None,
        provenance: Provenance {
            tool_version: "citywalk test".into(),
            inputs: vec![InputFile {
                path: "city.geojson".into(),
                size_bytes: 123,
                sha256: Some("00".repeat(32)),
            }],
            parameters_json: "{}".into(),
            load_report: LoadReport {
                buildings_found: 3,
                buildings_loaded: 2,
                ..LoadReport::default()
            },
            counts,
            skipped_stages: vec![],
            warnings: vec!["a warning".into()],
        },
        timings: vec![],
        gpu_scene,
        spilled: Vec::new(),
    };
    package.ground_surfaces = GroundSurfaces::of(&package.streets, &package.ground_areas);
    assert!(!package.ground_surfaces.draws.is_empty());
    package
}

fn city_of(buildings: &[Building]) -> City {
    City {
        frame: Frame::wgs84(-8.61, 41.15),
        buildings: buildings.to_vec(),
        streets: vec![],
        ground_areas: Vec::new(),
        report: LoadReport::default(),
    }
}

#[test]
fn a_package_round_trips_through_bytes_and_a_file() {
    let pkg = small_package();
    assert_eq!(pkg.check_invariants(), Ok(()));
    let bytes = pkg.to_bytes(WriteOptions::default()).expect("encode");
    assert_eq!(&bytes[..4], &MAGIC);
    let back = ScenePackage::from_bytes(&bytes).expect("decode");
    assert_eq!(back, pkg);

    let dir = std::env::temp_dir().join(format!("citywalk-package-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join("small.cwk");
    pkg.write(&path, WriteOptions::default()).expect("write");
    let file = PackageFile::open(&path).expect("open");
    assert!(file.section(SectionKind::Buildings).is_some());
    assert!(file.section(SectionKind::Occluders).is_none());
    for e in file.sections() {
        assert_eq!(e.offset % format::SECTION_ALIGN, 0);
    }
    assert_eq!(file.decode().expect("decode mapped"), pkg);
    let quadtree: Option<BQuadtree> = file
        .decode_section(SectionKind::Quadtree)
        .expect("decode one section");
    assert_eq!(quadtree.as_ref(), Some(&pkg.quadtree));
    let none: Option<OccluderSet> = file
        .decode_section(SectionKind::Occluders)
        .expect("no section is not an error");
    assert!(none.is_none());
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn encoding_is_deterministic_and_timings_stay_out_unless_asked() {
    let mut a = small_package();
    let b = small_package();
    a.timings = vec![StageTiming {
        stage: "blocks".into(),
        seconds: 0.123,
    }];
    let bytes_a = a.to_bytes(WriteOptions::default()).expect("encode");
    let bytes_b = b.to_bytes(WriteOptions::default()).expect("encode");
    assert_eq!(bytes_a, bytes_b);
    let with = a
        .to_bytes(WriteOptions {
            include_timings: true,
        })
        .expect("encode");
    assert_ne!(with, bytes_a);
    assert_eq!(
        ScenePackage::from_bytes(&with).expect("decode").timings,
        a.timings
    );
}

/// A section spilled to a scratch file ahead of the write is written as its value would
/// have been: the same package bytes, whichever section, an optional one included.
#[test]
fn a_spilled_section_is_written_as_its_value() {
    let dir = tempfile::tempdir().expect("temp dir");
    let whole = small_package();
    let bytes = whole.to_bytes(WriteOptions::default()).expect("encode");
    let mut spilled = whole.clone();
    let streets = SpilledSection::encode(SectionKind::Streets, &spilled.streets, dir.path())
        .expect("spill the streets");
    spilled.streets.clear();
    spilled.spilled.push(streets);
    assert!(spilled.to_bytes(WriteOptions::default()).expect("encode") == bytes);
    // An optional section whose field is left empty.
    let mut with_timings = whole.clone();
    with_timings.timings = vec![StageTiming {
        stage: "blocks".into(),
        seconds: 0.5,
    }];
    let options = WriteOptions {
        include_timings: true,
    };
    let expected = with_timings.to_bytes(options).expect("encode");
    let timings = SpilledSection::encode(SectionKind::Timings, &with_timings.timings, dir.path())
        .expect("spill the timings");
    spilled.timings.clear();
    spilled.spilled.push(timings);
    assert!(spilled.to_bytes(options).expect("encode") == expected);
    let path = dir.path().join("spilled.cwk");
    spilled.write(&path, options).expect("write");
    assert!(std::fs::read(&path).expect("read") == expected);
    assert_eq!(
        std::fs::read_dir(dir.path()).expect("list").count(),
        1,
        "the scratch files have no name"
    );
}

#[test]
fn every_truncation_is_refused_as_truncated() {
    let bytes = small_package()
        .to_bytes(WriteOptions::default())
        .expect("encode");
    assert!(matches!(
        ScenePackage::from_bytes(&[]),
        Err(PackageError::NotAPackage)
    ));
    for len in 1..bytes.len() {
        match ScenePackage::from_bytes(&bytes[..len]) {
            Err(PackageError::Truncated { .. }) => {}
            other => panic!("prefix of {len} bytes: {other:?}"),
        }
    }
}

#[test]
fn other_files_and_versions_are_refused() {
    assert!(matches!(
        ScenePackage::from_bytes(b"{\"type\": \"FeatureCollection\"}"),
        Err(PackageError::NotAPackage)
    ));
    assert!(matches!(
        ScenePackage::from_bytes(b"\x89PNG\r\n\x1a\n"),
        Err(PackageError::NotAPackage)
    ));
    let mut bytes = small_package()
        .to_bytes(WriteOptions::default())
        .expect("encode");
    assert!(matches!(
        ScenePackage::from_bytes(b"CWK\0\x08\0\0\0"),
        Err(PackageError::Version {
            path: None,
            found: 8,
            supported: FORMAT_VERSION
        })
    ));
    let next = FORMAT_VERSION + 1;
    bytes[4..8].copy_from_slice(&next.to_le_bytes());
    assert!(matches!(
        ScenePackage::from_bytes(&bytes),
        Err(PackageError::Version {
            found,
            supported: FORMAT_VERSION,
            ..
        }) if found == next
    ));
}

#[test]
fn corrupted_sections_and_headers_name_what_is_broken() {
    let bytes = small_package()
        .to_bytes(WriteOptions::default())
        .expect("encode");
    let entries = format::verify(&bytes).expect("verify");
    for e in &entries {
        let mut bad = bytes.clone();
        bad[(e.offset + e.length / 2) as usize] ^= 0x10;
        let name = SectionKind::from_u32(e.kind).expect("kind").name();
        match ScenePackage::from_bytes(&bad) {
            Err(PackageError::Checksum { section }) => assert_eq!(section, name),
            other => panic!("section {name}: {other:?}"),
        }
    }
    // A length in the table (bytes 16 + 16..24 of the first entry).
    let mut bad = bytes.clone();
    bad[16 + 16] ^= 0x01;
    assert!(matches!(
        ScenePackage::from_bytes(&bad),
        Err(PackageError::Checksum { section }) if section == "header"
    ));
    // Trailing garbage.
    let mut long = bytes.clone();
    long.push(0);
    assert!(matches!(
        ScenePackage::from_bytes(&long),
        Err(PackageError::Malformed(_))
    ));
}

#[test]
fn flipping_any_single_byte_gives_an_error_never_a_panic_or_another_package() {
    let bytes = small_package()
        .to_bytes(WriteOptions {
            include_timings: true,
        })
        .expect("encode");
    for position in 0..bytes.len() {
        for flip in [0x01u8, 0x80, 0xff] {
            let mut bad = bytes.clone();
            bad[position] ^= flip;
            let result = std::panic::catch_unwind(|| ScenePackage::from_bytes(&bad));
            match result {
                Ok(Err(_)) => {}
                Ok(Ok(_)) => panic!("byte {position} ^ {flip:#x}: accepted"),
                Err(_) => panic!("byte {position} ^ {flip:#x}: panicked"),
            }
        }
    }
}

#[test]
fn the_package_checker_reports_broken_structures() {
    let mut lost = small_package();
    lost.blocks.block_of_building.pop();
    let errors = lost
        .check_invariants()
        .expect_err("a building without a block");
    assert!(
        errors.iter().any(|e| e.starts_with("blocks, buildings:")),
        "{errors:?}"
    );

    let mut moved = small_package();
    moved.quadtree.block_bounds[0].max[0] += 1.0;
    let errors = moved.check_invariants().expect_err("boxes disagree");
    assert!(
        errors.iter().any(|e| e.starts_with("quadtree, blocks:")),
        "{errors:?}"
    );
}

#[test]
fn the_gpu_scene_round_trips_and_is_read_in_place_from_the_mapping() {
    let pkg = small_package();
    let city = pkg.city();
    let view = pkg.gpu_scene.view();
    assert_eq!(view.building_count, 2);
    assert_eq!(view.cluster_count(), 0);
    assert_eq!(pkg.gpu_scene.geometry(), SceneGeometry::from_city(&city));
    assert_eq!(view.cull_records, view.records);
    assert!(
        view.parents
            .iter()
            .all(|&p| p == citywalk_shaders::constants::NO_PARENT)
    );
    assert_eq!(view.check_invariants(2, 0), Ok(()));

    let bytes = pkg.to_bytes(WriteOptions::default()).expect("encode");
    let back = ScenePackage::from_bytes(&bytes).expect("decode");
    assert!(!back.gpu_scene.is_mapped());
    assert_eq!(back.gpu_scene, pkg.gpu_scene);

    let dir = std::env::temp_dir().join(format!("citywalk-gpu-scene-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join("small.cwk");
    pkg.write(&path, WriteOptions::default()).expect("write");
    let file = PackageFile::open(&path).expect("open");
    let payload = file
        .section(SectionKind::GpuScene)
        .expect("gpu scene section");
    assert_eq!(payload, pkg.gpu_scene.bytes());
    let mapped = file.decode().expect("decode mapped");
    drop(file);
    // The scene's arrays are the mapping's bytes, alive after the file handle is gone.
    assert!(mapped.gpu_scene.is_mapped());
    assert_eq!(mapped.gpu_scene.view(), view);
    assert_eq!(mapped, pkg);
    // Pages given back after an upload are read again from the file, unchanged; an owned
    // scene is left alone.
    let mapped_view = mapped.gpu_scene.view();
    mapped_view.release_resident(mapped.gpu_scene.bytes());
    assert_eq!(mapped.gpu_scene.bytes(), pkg.gpu_scene.bytes());
    assert_eq!(mapped.gpu_scene.view(), view);
    view.release_resident(pkg.gpu_scene.bytes());
    assert_eq!(pkg.gpu_scene.bytes(), back.gpu_scene.bytes());
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn an_old_package_is_refused_naming_the_file_and_the_fix() {
    let mut bytes = small_package()
        .to_bytes(WriteOptions::default())
        .expect("encode");
    bytes[4..8].copy_from_slice(&2u32.to_le_bytes());
    let dir = std::env::temp_dir().join(format!("citywalk-old-package-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join("old.cwk");
    std::fs::write(&path, &bytes).expect("write");
    let error = ScenePackage::read(&path).expect_err("version 2 is refused");
    assert!(
        matches!(&error, PackageError::Version { path: Some(p), found: 2, .. } if *p == path),
        "{error:?}"
    );
    let message = error.to_string();
    assert!(message.contains(&path.display().to_string()), "{message}");
    assert!(
        message.contains("re-run `citywalk preprocess`"),
        "{message}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// `bytes` with the GPU scene's payload replaced by `edit` of it, the sections after it moved
/// and the checksums made to match: what a faulty writer could produce.
fn with_gpu_payload(bytes: &[u8], edit: impl FnOnce(&mut Vec<u8>)) -> Vec<u8> {
    let entries = format::verify(bytes).expect("verify");
    let mut payloads: Vec<Vec<u8>> = entries
        .iter()
        .map(|e| bytes[e.offset as usize..(e.offset + e.length) as usize].to_vec())
        .collect();
    let i = (entries.iter())
        .position(|e| e.kind == SectionKind::GpuScene as u32)
        .expect("gpu scene section");
    edit(&mut payloads[i]);
    // The header and table as they were, then each payload at the next aligned offset.
    let mut out = bytes[..16 + 32 * entries.len()].to_vec();
    for (k, payload) in payloads.iter().enumerate() {
        let offset = (out.len() as u64).next_multiple_of(format::SECTION_ALIGN);
        out.resize(offset as usize, 0);
        let entry = 16 + 32 * k;
        out[entry + 8..entry + 16].copy_from_slice(&offset.to_le_bytes());
        out[entry + 16..entry + 24].copy_from_slice(&(payload.len() as u64).to_le_bytes());
        out[entry + 24..entry + 28].copy_from_slice(&crc32fast::hash(payload).to_le_bytes());
        out.extend_from_slice(payload);
    }
    let crc = format::header_crc(&out);
    out[12..16].copy_from_slice(&crc.to_le_bytes());
    out
}

#[test]
fn an_inconsistent_gpu_scene_is_refused() {
    let pkg = small_package();
    let bytes = pkg.to_bytes(WriteOptions::default()).expect("encode");
    assert_eq!(
        ScenePackage::from_bytes(&with_gpu_payload(&bytes, |_| {})).expect("unchanged"),
        pkg
    );
    let u32_at = |p: &[u8], at: usize| u32::from_le_bytes(p[at..at + 4].try_into().unwrap());
    type Edit = Box<dyn Fn(&mut Vec<u8>)>;
    let cases: [(&str, Edit); 5] = [
        ("cut short", Box::new(|p| p.truncate(p.len() - 16))),
        // Header field 3: the index count, one triangle more than the arrays hold.
        (
            "counts",
            Box::new(move |p| {
                let n = u32_at(p, 12) + 3;
                p[12..16].copy_from_slice(&n.to_le_bytes());
            }),
        ),
        // Header words 8..12 are reserved (after the five counts and three occluder counts).
        ("reserved", Box::new(|p| p[32] = 1)),
        ("padding", Box::new(|p| *p.last_mut().unwrap() = 1)),
        // The first draw record (after the header, the vertices and the indices, padded to 16
        // bytes): its index count (at 28 in the record) past the index array.
        (
            "record",
            Box::new(move |p| {
                let (vertices, indices) = (u32_at(p, 8) as usize, u32_at(p, 12) as usize);
                let record = 96 + 16 * vertices + (4 * indices).next_multiple_of(16);
                p[record + 28..record + 32].copy_from_slice(&1000u32.to_le_bytes());
            }),
        ),
    ];
    for (what, edit) in cases {
        match ScenePackage::from_bytes(&with_gpu_payload(&bytes, edit)) {
            Err(PackageError::Decode { section, .. }) if section == "gpu scene" => {}
            other => panic!("{what}: {other:?}"),
        }
    }

    // A scene of other buildings than the package's.
    let mut other = small_package();
    other.gpu_scene = GpuScene::build(&city_of(&other.buildings[..1]), None, None);
    let bytes = other.to_bytes(WriteOptions::default()).expect("encode");
    match ScenePackage::from_bytes(&bytes) {
        Err(PackageError::Inconsistent { sections, reason }) if sections.contains("gpu scene") => {
            assert!(reason.contains("1 buildings"), "{reason}");
        }
        other => panic!("{other:?}"),
    }

    // Well-formed but not the buildings' geometry: the checker finds it.
    let mut moved = small_package();
    let mut geometry = moved.gpu_scene.geometry();
    geometry.vertices[0].position_m[2] += 1.0;
    moved.gpu_scene = GpuScene::from_arrays(2, geometry, None, None, Default::default());
    let errors = moved.check_invariants().expect_err("moved vertex");
    assert!(
        errors.iter().any(|e| e.starts_with("gpu scene:")),
        "{errors:?}"
    );
    let mut relabelled = small_package();
    let mut geometry = relabelled.gpu_scene.geometry();
    geometry.vertices[0].building_id = 1;
    relabelled.gpu_scene = GpuScene::from_arrays(2, geometry, None, None, Default::default());
    let errors = relabelled
        .check_invariants()
        .expect_err("vertex of another building");
    assert!(
        errors.iter().any(|e| e.contains("another id")),
        "{errors:?}"
    );
}

/// Issue 14 case 1: `preprocess … -o /dev/full` reported success and replaced the device node
/// (the temporary file was renamed over it). A named pipe stands in for the device here; a
/// folder, a symbolic link to the pipe and a read-only file are refused the same way, and none
/// of them is changed.
#[cfg(unix)]
#[test]
fn writing_over_a_device_pipe_folder_or_read_only_file_fails_and_leaves_it() {
    use std::os::unix::fs::{FileTypeExt, PermissionsExt};
    let pkg = small_package();
    let dir = tempfile::tempdir().expect("temp dir");
    let fifo = dir.path().join("pipe.cwk");
    let made = std::process::Command::new("mkfifo").arg(&fifo).status();
    assert!(
        made.as_ref().is_ok_and(|s| s.success()),
        "mkfifo failed: {made:?}"
    );
    let err = pkg.write(&fifo, WriteOptions::default()).unwrap_err();
    assert!(matches!(err, PackageError::NotWritable { .. }), "{err}");
    assert!(err.to_string().contains("named pipe"), "{err}");
    let kind = std::fs::symlink_metadata(&fifo).expect("pipe").file_type();
    assert!(kind.is_fifo(), "the pipe was replaced");
    let link = dir.path().join("link.cwk");
    std::os::unix::fs::symlink(&fifo, &link).expect("symlink");
    let err = pkg.write(&link, WriteOptions::default()).unwrap_err();
    assert!(err.to_string().contains("named pipe"), "{err}");
    assert!(std::fs::symlink_metadata(&link).expect("link").is_symlink());
    let folder = dir.path().join("folder.cwk");
    std::fs::create_dir(&folder).expect("folder");
    let err = pkg.write(&folder, WriteOptions::default()).unwrap_err();
    assert!(err.to_string().contains("a folder"), "{err}");
    assert!(folder.is_dir());

    let read_only = dir.path().join("read-only.cwk");
    std::fs::write(&read_only, b"keep").expect("file");
    std::fs::set_permissions(&read_only, std::fs::Permissions::from_mode(0o444)).expect("chmod");
    let err = pkg.write(&read_only, WriteOptions::default()).unwrap_err();
    assert!(err.to_string().contains("read-only"), "{err}");
    assert_eq!(std::fs::read(&read_only).expect("kept"), b"keep");

    // Only the refused targets and the link are left: no temporary file stays behind.
    let names = std::fs::read_dir(dir.path()).expect("list").count();
    assert!(names <= 4, "{names} entries");
}

/// Issue 14 case 1 itself (`-o /dev/full`): a character device, named or behind a link, is
/// refused as one. Only the target check runs here: a test that wrote to a device
/// would replace the test machine's own if the check failed.
#[cfg(unix)]
#[test]
fn a_character_device_is_refused_as_one_before_anything_is_written() {
    let dir = tempfile::tempdir().expect("temp dir");
    let link = dir.path().join("to-dev-null.cwk");
    std::os::unix::fs::symlink("/dev/null", &link).expect("symlink");
    for target in [Path::new("/dev/null"), link.as_path()] {
        let err = writable_target(target).unwrap_err();
        assert!(matches!(err, PackageError::NotWritable { .. }), "{err}");
        let text = err.to_string();
        assert!(
            text.contains("a character device") && text.contains("left as it is"),
            "{text}"
        );
        assert!(text.contains(&target.display().to_string()), "{text}");
    }
}

/// The file `write` streams, section by section with the table written last, is byte for byte
/// the package `to_bytes` encodes in memory, with and without the optional sections.
#[test]
fn a_written_file_is_the_encoded_package() {
    let dir = tempfile::tempdir().expect("temp dir");
    let mut pkg = small_package();
    for round in 0..2 {
        for options in [
            WriteOptions::default(),
            WriteOptions {
                include_timings: true,
            },
        ] {
            let path = dir
                .path()
                .join(format!("city-{round}-{}.cwk", options.include_timings));
            let length = pkg.write(&path, options).expect("write");
            let written = std::fs::read(&path).expect("read");
            assert_eq!(length, written.len() as u64);
            assert!(
                written == pkg.to_bytes(options).expect("encode"),
                "round {round}"
            );
            assert_eq!(
                ScenePackage::read(&path).expect("reopen").buildings,
                pkg.buildings
            );
        }
        // Again without the optional occluder set and cluster tree.
        pkg.occluders = None;
        pkg.cluster_tree = None;
        pkg.gpu_scene = GpuScene::build(&pkg.city(), None, None);
    }
}

/// Sections are encoded straight into the writer: a write that fails partway through one (a
/// full disk) is reported with its own cause, whichever section it hits, never as a failure
/// to encode.
#[test]
fn a_write_failing_inside_a_section_reports_its_cause() {
    /// A file that takes `room` bytes and then is full.
    struct FullAfter {
        inner: std::io::Cursor<Vec<u8>>,
        room: u64,
    }
    impl std::io::Write for FullAfter {
        fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
            let left = self.room.saturating_sub(self.inner.position()) as usize;
            if left == 0 && !buf.is_empty() {
                return Err(std::io::Error::new(
                    std::io::ErrorKind::StorageFull,
                    "no space left on the test device",
                ));
            }
            self.inner.write(&buf[..buf.len().min(left)])
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }
    impl std::io::Seek for FullAfter {
        fn seek(&mut self, to: std::io::SeekFrom) -> std::io::Result<u64> {
            self.inner.seek(to)
        }
    }
    let pkg = small_package();
    let whole = pkg.to_bytes(WriteOptions::default()).expect("encode");
    for room in [0, 200, whole.len() as u64 / 3, whole.len() as u64 - 1] {
        let mut out = FullAfter {
            inner: Default::default(),
            room,
        };
        let err = format::encode_to(&pkg, WriteOptions::default(), &mut out, |e| {
            PackageError::Io {
                path: "test.cwk".into(),
                source: e,
            }
        })
        .expect_err("a full device");
        assert!(
            matches!(&err, PackageError::Io { source, .. }
                if source.kind() == std::io::ErrorKind::StorageFull),
            "room {room}: {err}"
        );
    }
}

/// A package written over an existing regular file or through a symbolic link replaces the
/// file the link points to (keeping its permissions), and the link stays a link.
#[cfg(unix)]
#[test]
fn writing_replaces_a_regular_file_and_follows_a_link() {
    use std::os::unix::fs::PermissionsExt;
    let pkg = small_package();
    let dir = tempfile::tempdir().expect("temp dir");
    let file = dir.path().join("city.cwk");
    std::fs::write(&file, b"old").expect("file");
    std::fs::set_permissions(&file, std::fs::Permissions::from_mode(0o640)).expect("chmod");
    let link = dir.path().join("link.cwk");
    std::os::unix::fs::symlink(&file, &link).expect("symlink");
    pkg.write(&link, WriteOptions::default()).expect("write");
    assert!(std::fs::symlink_metadata(&link).expect("link").is_symlink());
    assert_eq!(ScenePackage::read(&file).expect("read"), pkg);
    let mode = std::fs::metadata(&file).expect("meta").permissions().mode();
    assert_eq!(mode & 0o777, 0o640);
    assert_eq!(std::fs::read_dir(dir.path()).expect("list").count(), 2);
}

#[test]
fn one_buildings_details_are_read_alone_as_a_full_decode_gives_them() {
    let mut pkg = small_package();
    // Building 0: two parts, one a multipolygon with a hole, and several tags; building 1
    // without parts or tags; building 2 with levels. Reading a building walks past the ones
    // before it, so every shape of entry is walked past once.
    let holed = MultiPolygon::new(vec![
        polygon![
            exterior: [(x: 0.0, y: 0.0), (x: 8.0, y: 0.0), (x: 8.0, y: 6.0), (x: 0.0, y: 6.0)],
            interiors: [[(x: 2.0, y: 2.0), (x: 4.0, y: 2.0), (x: 4.0, y: 4.0)]],
        ],
        polygon![(x: 10.0, y: 0.0), (x: 12.0, y: 0.0), (x: 12.0, y: 2.0)],
    ]);
    pkg.buildings[0].parts.push(BuildingPart {
        source_id: "way/100".into(),
        footprint: holed,
        base_m: 12.5,
        top_m: 20.0,
    });
    pkg.buildings[0]
        .tags
        .insert("name".into(), "Torre dos Clérigos".into());
    pkg.buildings[1].parts.clear();
    pkg.buildings[1].tags.clear();
    let mut third = pkg.buildings[0].clone();
    third.id = BuildingId(2);
    third.tags.insert("building:levels".into(), "7".into());
    pkg.buildings.push(third);
    pkg.blocks.blocks[0].buildings.push(BuildingId(2));
    pkg.blocks.block_of_building.push(0);
    pkg.gpu_scene = GpuScene::build(&city_of(&pkg.buildings), None, None);

    let bytes = pkg.to_bytes(WriteOptions::default()).expect("encode");
    let full = ScenePackage::from_bytes(&bytes).expect("decode all");
    let entries = format::verify(&bytes).expect("verify");
    for (i, b) in full.buildings.iter().enumerate() {
        let details = format::read_building_details(&bytes, &entries, i).expect("read");
        assert_eq!(details.parts, b.parts, "building {i}");
        assert_eq!(details.tags, b.tags, "building {i}");
        assert_eq!(details.levels_tag(), b.levels_tag(), "building {i}");
    }
    assert_eq!(
        format::read_building_details(&bytes, &entries, 2)
            .expect("read")
            .levels_tag(),
        Some("7")
    );
    let past = format::read_building_details(&bytes, &entries, 3).expect_err("out of range");
    assert!(
        matches!(past, PackageError::NoSuchBuilding { index: 3, count: 3 }),
        "{past:?}"
    );
    assert_eq!(past.to_string(), "no building 3: the package has 3");

    // From a mapped file, as the viewer reads them.
    let dir = std::env::temp_dir().join(format!("citywalk-details-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join("details.cwk");
    pkg.write(&path, WriteOptions::default()).expect("write");
    let file = PackageFile::open(&path).expect("open");
    let drawn = file.decode_as(Decode::RuntimeWithParts).expect("decode");
    assert!(drawn.buildings.iter().all(|b| b.tags.is_empty()));
    assert_eq!(
        file.building_details(0).expect("read").tags,
        full.buildings[0].tags
    );
    assert!(file.building_details(usize::MAX).is_err());
    std::fs::remove_dir_all(&dir).ok();
}
