//! LuGre's host layouts' tests: the buffers' Rust structs against naga's
//! layout of the shader.

use super::*;
use crate::gpu::lugre::{Arithmetic, Form, SOFTWARE_WORKGROUP_SIZE, parse_and_validate};

/// The buffers' Rust structs have the shader's layout.
#[test]
pub(super) fn params_and_lanes_have_the_shader_layout() {
    let (module, _) =
        parse_and_validate(SOFTWARE_WORKGROUP_SIZE, Arithmetic::Native, Form::Sawtooth).unwrap();
    let mut layouter = naga::proc::Layouter::default();
    layouter.update(module.to_ctx()).unwrap();
    let find = |name: &str| {
        module
            .types
            .iter()
            .find(|(_, t)| t.name.as_deref() == Some(name))
            .unwrap_or_else(|| panic!("no {name}"))
    };
    let offsets = |name: &str| -> (u32, Vec<(String, u32)>) {
        let (handle, ty) = find(name);
        let naga::TypeInner::Struct { members, span } = &ty.inner else {
            panic!("{name} is no struct")
        };
        assert_eq!(layouter[handle].size, *span);
        (
            *span,
            members
                .iter()
                .map(|m| (m.name.clone().unwrap(), m.offset))
                .collect(),
        )
    };
    let (span, members) = offsets("Model");
    assert_eq!(span as usize, size_of::<Params>());
    let rust = [
        ("gain", std::mem::offset_of!(Params, gain)),
        ("load", std::mem::offset_of!(Params, load)),
        ("slider_mass", std::mem::offset_of!(Params, slider_mass)),
        ("period", std::mem::offset_of!(Params, period)),
        ("scale", std::mem::offset_of!(Params, scale)),
        ("one", std::mem::offset_of!(Params, one)),
        ("common_period", std::mem::offset_of!(Params, common_period)),
        ("corner_first", std::mem::offset_of!(Params, corner_first)),
        ("corner_count", std::mem::offset_of!(Params, corner_count)),
    ];
    for (name, offset) in rust {
        let (_, o) = members.iter().find(|(n, _)| n == name).unwrap();
        assert_eq!(*o as usize, offset, "Model.{name}");
    }
    let (span, members) = offsets("Coefficients");
    assert_eq!(span as usize, size_of::<Coefficients>());
    let rust = <Coefficients as crate::gpu::layout::HostLayout>::members();
    assert_eq!(rust.len(), members.len(), "Coefficients' members");
    for (name, offset) in rust {
        let (_, o) = members.iter().find(|(n, _)| n == name).unwrap();
        assert_eq!(*o as usize, offset, "Coefficients.{name}");
    }
    let (span, members) = offsets("Lane");
    assert_eq!(span as usize, size_of::<Lane>());
    // Every member the engine's `HostLayout` names, at WGSL's offset.
    let rust = <Lane as crate::gpu::layout::HostLayout>::members();
    assert_eq!(rust.len(), members.len() - 1, "Lane's members but `_pad`");
    for (name, offset) in rust {
        let (_, o) = members.iter().find(|(n, _)| n == name).unwrap();
        assert_eq!(*o as usize, offset, "Lane.{name}");
    }
}

/// The host's `StageMatrix` is the shader's `W`, member for member
/// (`Lu`'s `a` and `pivot` as its first two).
#[test]
fn the_stage_matrix_has_the_shader_layout() {
    let (module, _) =
        parse_and_validate(SOFTWARE_WORKGROUP_SIZE, Arithmetic::Native, Form::Sawtooth).unwrap();
    let member = |name: &str, field: &str| {
        let (_, ty) = module
            .types
            .iter()
            .find(|(_, t)| t.name.as_deref() == Some(name))
            .unwrap_or_else(|| panic!("no {name}"));
        let naga::TypeInner::Struct { members, span } = &ty.inner else {
            panic!("{name} is no struct")
        };
        let m = members.iter().find(|m| m.name.as_deref() == Some(field));
        (
            *span,
            m.unwrap_or_else(|| panic!("no {name}.{field}")).offset,
        )
    };
    let (span, lu) = member("W", "lu");
    assert_eq!(span as usize, size_of::<StageMatrix>());
    assert_eq!(lu as usize, std::mem::offset_of!(StageMatrix, lu));
    let (_, pivot) = member("Lu", "pivot");
    assert_eq!(
        (lu + pivot) as usize,
        std::mem::offset_of!(StageMatrix, pivot)
    );
    for (field, offset) in [
        ("g", std::mem::offset_of!(StageMatrix, g)),
        ("j_xp", std::mem::offset_of!(StageMatrix, j_xp)),
        ("j_t", std::mem::offset_of!(StageMatrix, j_t)),
    ] {
        assert_eq!(member("W", field).1 as usize, offset, "W.{field}");
    }
}

/// The largest table (64 entries, 32 jumps between -1 and 1) under
/// amplifier slew limits from barely biting to a crawl keeps its axis
/// within the waveform pipeline's `MAX_CORNERS`, and the corner buffer
/// locates each axis' corners in its parameters.
#[test]
fn the_largest_slew_limited_table_fits_the_corner_search() {
    use crate::laws::Settings;
    use crate::laws::floor::drive::{MAX_TABLE_ENTRIES, axis_corners};
    use crate::model::{Instance, Shape, Table};
    let entries: Vec<[f64; 2]> = (0..MAX_TABLE_ENTRIES / 2)
        .flat_map(|k| {
            let u = k as f64 / (MAX_TABLE_ENTRIES / 2) as f64;
            let level = if k % 2 == 0 { 1.0 } else { -1.0 };
            [[u, level], [u, -level]]
        })
        .collect();
    let mut inst = Instance::TABLE1;
    inst.axes[0].shape = Shape::Table(Table::intern(&entries));
    let unlimited = axis_corners(&inst.axes[0]);
    for slew in [1e7, 1e6, 1e5, 3e4, 1e4, 3e3] {
        inst.axes[0].slew_rate = slew;
        let corners = axis_corners(&inst.axes[0]);
        assert_ne!(corners, unlimited, "slew rate {slew} bites");
        let n = corners.points.len();
        assert!(
            n <= crate::gpu::lugre::MAX_CORNERS,
            "slew rate {slew}: {n} corners"
        );
    }
    // docs/model.md section 8's interface (its default keys, by name).
    let law = crate::laws::Law::from_name("lugre").expect("a law");
    inst.mechanism.friction = law.friction([1e7, f64::NAN, 0.0, 1e-3]);
    let books = [Periods::new(&inst, &Settings::default())];
    let mut params = [Params::of(&books[0])];
    let corners = corner_buffer(&books, &mut params).unwrap();
    let counts = params[0].corner_count;
    assert_eq!(params[0].corner_first, [0, counts[0]]);
    assert_eq!(corners.len(), (counts[0] + counts[1]) as usize);
    assert_eq!(corners[0].u, books[0].drives[0].points[0][0]);
}
