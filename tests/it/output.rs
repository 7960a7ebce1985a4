//! The HDF5 result file read back: layout, units, values, and that a file
//! is complete or absent.

use hdf5::types::VarLenUnicode;
use pidm::model::motion::Motion;
use pidm::output::{AxisInfo, FileInfo, MapWriter, OutputClaim, schema};
use pidm::sweep::Record;

fn info(shape: Vec<usize>, baselines: bool) -> FileInfo {
    FileInfo {
        name: "t".into(),
        scene_text: "name = \"t\"\n".into(),
        axes: shape
            .iter()
            .enumerate()
            .map(|(d, &n)| AxisInfo {
                key: format!("axis.x.key{d}"),
                values: (0..n).map(|v| v as f64).collect(),
                units: "V".into(),
            })
            .collect(),
        shape,
        labels: None,
        baselines,
        backend: "cpu (test)".into(),
        precision: "f64".into(),
        variant: "2-DOF".into(),
        tolerance: 1e-4,
        friction: "karnopp".to_owned(),
        friction_parameters: None,
        verify_tolerance: None,
        shard: None,
        stall: None,
        backward: false,
    }
}

/// The kind of motion of `record(i)`: every kind in turn where the status
/// is 0, undetermined elsewhere (a failed run has no kind).
fn motion(i: usize) -> Motion {
    if i.is_multiple_of(3) {
        Motion::ALL[(i / 3) % Motion::ALL.len()]
    } else {
        Motion::Undetermined
    }
}

fn record(i: usize) -> Record {
    Record {
        step: [i as f64 * 1e-9, -(i as f64) * 1e-9],
        velocity: [i as f64, 2.0 * i as f64],
        status: (i % 3) as u32,
        steps: i as u32 * 10,
        step_se: [i as f64 * 1e-12, 0.0],
        periods: 10 + i as u32,
        period_lag: (i % 2) as u32,
        motion: motion(i),
        replicas: 1 + (i % 4) as u32,
        baseline_step: [i as f64 + 0.5, i as f64 - 0.5],
        baseline_status: 0,
        backward: Default::default(),
    }
}

#[test]
fn maps_written_in_uneven_chunks_read_back_in_grid_order() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("out.h5");
    let shape = vec![3, 4, 5];
    let n = 60;
    let claim = OutputClaim::acquire(&path).unwrap();
    let mut writer = MapWriter::create(&claim, &info(shape.clone(), true)).unwrap();
    // Uneven chunks that cut rows and planes.
    let mut start = 0;
    for len in [7, 1, 13, 20, 19] {
        let recs: Vec<Record> = (start..start + len).map(record).collect();
        writer.write(start as u64, &recs).unwrap();
        start += len;
    }
    assert_eq!(start, n);
    assert!(!path.exists(), "the final name appears only when complete");
    writer.finish(&[1.0, 0.25]).unwrap();

    let file = hdf5::File::open(&path).unwrap();
    let step_x = file.dataset("maps/step_x").unwrap();
    assert_eq!(step_x.shape(), shape);
    let values: Vec<f64> = step_x.read_raw().unwrap();
    let want: Vec<f64> = (0..n).map(|i| record(i).step[0]).collect();
    assert_eq!(values, want);
    let status: Vec<u32> = file.dataset("maps/status").unwrap().read_raw().unwrap();
    assert_eq!(status, (0..n).map(|i| (i % 3) as u32).collect::<Vec<_>>());
    let base_y: Vec<f64> = file.dataset("baseline/step_y").unwrap().read_raw().unwrap();
    assert_eq!(base_y[59], 58.5);
    let units: VarLenUnicode = step_x.attr("units").unwrap().read_scalar().unwrap();
    assert_eq!(units.as_str(), "m");
    let axis = file.dataset("axes/axis.x.key1").unwrap();
    assert_eq!(axis.read_raw::<f64>().unwrap(), vec![0.0, 1.0, 2.0, 3.0]);
    let wall: f64 = file.attr("wall_time_s").unwrap().read_scalar().unwrap();
    assert_eq!(wall, 1.25);
    let parts: Vec<f64> = file.attr("wall_time_parts_s").unwrap().read_raw().unwrap();
    assert_eq!(parts, [1.0, 0.25]);
    for name in ["scene", "pidm_version", "backend", "precision"] {
        let v: VarLenUnicode = file.attr(name).unwrap().read_scalar().unwrap();
        assert!(!v.as_str().is_empty(), "{name}");
    }
}

/// `/maps/motion` reads back as u8 codes in grid order, with the CF
/// attributes that name them, the units and long name, the dimension
/// scales and the root link every map has.
#[test]
fn the_motion_map_reads_back_with_its_flags() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("out.h5");
    let shape = vec![4, 6];
    let claim = OutputClaim::acquire(&path).unwrap();
    let mut writer = MapWriter::create(&claim, &info(shape.clone(), false)).unwrap();
    let recs: Vec<Record> = (0..24).map(record).collect();
    writer.write(0, &recs[..11]).unwrap();
    writer.write(11, &recs[11..]).unwrap();
    writer.finish(&[0.5]).unwrap();

    let file = hdf5::File::open(&path).unwrap();
    let ds = file.dataset(schema::MOTION).unwrap();
    assert_eq!(ds.shape(), shape);
    assert!(ds.dtype().unwrap().is::<u8>(), "motion is u8");
    let codes: Vec<u8> = ds.read_raw().unwrap();
    let want: Vec<u8> = (0..24).map(|i| motion(i).code()).collect();
    assert_eq!(codes, want);
    // Every kind is there, so the read-back sees each code.
    for kind in Motion::ALL {
        assert!(codes.contains(&kind.code()), "{kind:?}");
    }
    let flag_values = ds.attr(schema::FLAG_VALUES).unwrap();
    assert!(flag_values.dtype().unwrap().is::<u8>(), "flag_values is u8");
    assert_eq!(flag_values.read_raw::<u8>().unwrap(), [0, 1, 2, 3, 4]);
    let text = |name: &str| -> String {
        let v: VarLenUnicode = ds.attr(name).unwrap().read_scalar().unwrap();
        v.as_str().to_owned()
    };
    assert_eq!(
        text(schema::FLAG_MEANINGS),
        "undetermined periodic quasi_periodic irregular multistable"
    );
    assert_eq!(text("units"), "1");
    assert!(text("long_name").contains("kind of motion"));
    // The same dimension scales as every map, and the root link.
    assert!(ds.attr("DIMENSION_LIST").is_ok());
    let step = file.dataset("maps/step_x").unwrap();
    assert_eq!(
        ds.attr_names().unwrap().len(),
        step.attr_names().unwrap().len() + 2,
        "the attributes of a map and the two flags"
    );
    let linked: Vec<u8> = file.dataset("motion").unwrap().read_raw().unwrap();
    assert_eq!(linked, want);
}

#[test]
fn a_writer_dropped_before_finishing_leaves_no_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("out.h5");
    {
        let claim = OutputClaim::acquire(&path).unwrap();
        let mut writer = MapWriter::create(&claim, &info(vec![4], false)).unwrap();
        writer.write(0, &[record(0), record(1)]).unwrap();
    }
    let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert!(left.is_empty(), "left behind: {left:?}");
}

#[test]
fn a_single_instance_scene_gives_scalar_maps() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("one.h5");
    let claim = OutputClaim::acquire(&path).unwrap();
    let mut writer = MapWriter::create(&claim, &info(vec![], false)).unwrap();
    writer.write(0, &[record(5)]).unwrap();
    writer.finish(&[0.0]).unwrap();
    let file = hdf5::File::open(&path).unwrap();
    let ds = file.dataset("maps/step_x").unwrap();
    assert!(ds.shape().is_empty());
    assert_eq!(ds.read_scalar::<f64>().unwrap(), 5e-9);
}
