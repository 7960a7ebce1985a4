//! The host structs against the shader's (naga), units and packing.

use super::*;
use crate::gpu::Precision;
use crate::laws::karnopp::integrate::Coefficients;
use naga::proc::Layouter;

/// Checks one naga struct against its host mirror.
fn check_struct<T: HostLayout>(module: &naga::Module, layouter: &Layouter, precision: Precision) {
    let (handle, ty) = module
        .types
        .iter()
        .find(|(_, ty)| ty.name.as_deref() == Some(T::NAME))
        .unwrap_or_else(|| panic!("{precision:?}: no struct {} in the shader", T::NAME));
    let naga::TypeInner::Struct { members, span } = &ty.inner else {
        panic!("{} is not a struct", T::NAME);
    };
    assert_eq!(
        *span as usize,
        size_of::<T>(),
        "{precision:?} {}: shader size {} vs host {}",
        T::NAME,
        span,
        size_of::<T>()
    );
    assert_eq!(layouter[handle].size as usize, size_of::<T>());
    let host = T::members();
    let shader: Vec<(&str, usize)> = members
        .iter()
        .map(|m| (m.name.as_deref().unwrap_or("?"), m.offset as usize))
        .collect();
    assert_eq!(
        shader,
        host,
        "{precision:?} {}: members (name, offset) differ",
        T::NAME
    );
}

#[test]
fn shader_layout_matches_host_structs() {
    for precision in [Precision::F32, Precision::F64] {
        let variant = crate::gpu::Variant {
            precision,
            loop_limiter: false,
            parts: crate::gpu::shader::Parts::ALL,
        };
        let (module, _info) = match crate::gpu::shader::parse_and_validate(variant) {
            Ok(m) => m,
            Err(e) => panic!("{e}"),
        };
        let mut layouter = Layouter::default();
        layouter
            .update(module.to_ctx())
            .expect("the shader's types lay out");
        check_struct::<control::Control>(&module, &layouter, precision);
        check_struct::<control::Tally>(&module, &layouter, precision);
        match precision {
            Precision::F32 => {
                check_struct::<single::Oscillator>(&module, &layouter, precision);
                check_struct::<single::Coefficients>(&module, &layouter, precision);
                check_struct::<single::State>(&module, &layouter, precision);
                check_struct::<single::Snapshot>(&module, &layouter, precision);
                check_struct::<single::Gaps>(&module, &layouter, precision);
                check_struct::<single::Phase>(&module, &layouter, precision);
                check_struct::<single::Measure>(&module, &layouter, precision);
                check_struct::<single::Head>(&module, &layouter, precision);
                check_struct::<single::Segment>(&module, &layouter, precision);
            }
            Precision::F64 => {
                check_struct::<double::Oscillator>(&module, &layouter, precision);
                check_struct::<double::Coefficients>(&module, &layouter, precision);
                check_struct::<double::State>(&module, &layouter, precision);
                check_struct::<double::Snapshot>(&module, &layouter, precision);
                check_struct::<double::Gaps>(&module, &layouter, precision);
                check_struct::<double::Phase>(&module, &layouter, precision);
                check_struct::<double::Measure>(&module, &layouter, precision);
                check_struct::<double::Head>(&module, &layouter, precision);
                check_struct::<double::Segment>(&module, &layouter, precision);
            }
        }
    }
}

#[test]
fn units_keep_the_force_unit_one_newton() {
    assert_eq!(Units::MICRO_MILLI.newton(), 1.0);
    assert_eq!(Units::SI.newton(), 1.0);
}

#[test]
fn packing_scales_the_paper_mechanism_to_order_one() {
    let p = single::pack(&Instance::TABLE1, &Settings::default());
    // w2 = k / m = 4e8 s^-2 = 400 ms^-2.
    assert!((p.slip.w2.x - 400.0).abs() < 1e-3);
    assert!((p.frequency.x - 0.01).abs() < 1e-9);
    assert!((p.period - 100.0).abs() < 1e-5);
    assert!((p.band2 - 1e-6).abs() < 1e-12);
    // f64 packs exactly the CPU's coefficients.
    let d = double::pack(&Instance::TABLE1, &Settings::default());
    let c = Coefficients::new(&Instance::TABLE1, &Settings::default(), f64::EPSILON);
    assert_eq!(d.stiffness.x, 1.0e6);
    assert_eq!(d.period, Instance::TABLE1.period());
    assert_eq!(d.cycles_per_period.x, 1.0);
    assert_eq!(d.stick.rate.y, c.stick.rate.y);
    assert_eq!(d.event_step_slip, c.event_step_slip);
}

/// Every member of an f64 shader state lands in the CPU state's member
/// of the same name, so the CPU continues exactly where the GPU stopped.
#[test]
fn f64_states_continue_on_the_cpu_member_by_member() {
    let pair = |k: f64| F64x2 { x: k, y: k + 0.5 };
    let mut st: double::State = bytemuck::Zeroable::zeroed();
    st.x_p = pair(1.0);
    st.v_p = pair(2.0);
    st.x_s = pair(3.0);
    st.v_s = pair(4.0);
    st.v_rel = pair(5.0);
    st.held = pair(6.0);
    st.settle_x_s = pair(7.0);
    st.cycle_phase = pair(8.0);
    st.next_corner = pair(9.0);
    st.time = 10.0;
    st.h_slip = 11.0;
    st.segment = U32x2 { x: 0, y: 1 };
    st.mode = 2;
    st.period = 13;
    st.status = 14;
    st.steps = 15;
    st.stalled = 16;
    st.rejections = 17;
    let cpu = double::to_cpu(&st);
    let v = |k: f64| crate::laws::floor::Vec2::new(k, k + 0.5);
    assert_eq!(
        [cpu.x_p, cpu.v_p, cpu.x_s, cpu.v_s, cpu.v_rel, cpu.held],
        [v(1.0), v(2.0), v(3.0), v(4.0), v(5.0), v(6.0)]
    );
    assert_eq!(
        [cpu.settle_x_s, cpu.cycle_phase, cpu.next_corner],
        [v(7.0), v(8.0), v(9.0)]
    );
    assert_eq!([cpu.time, cpu.h_slip], [10.0, 11.0]);
    assert_eq!(cpu.segment, [0, 1]);
    assert_eq!(
        [
            cpu.mode,
            cpu.period,
            cpu.status,
            cpu.steps,
            cpu.stalled,
            cpu.rejections
        ],
        [2, 13, 14, 15, 16, 17]
    );
}

/// A waveform batch's segments, made from the instances alone
/// (`Coefficients::segments_of`), are every precision's coefficients'
/// segments, bit for bit: trapezoids, tables with jumps, slew limits.
#[test]
fn segments_of_an_instance_are_its_coefficients_segments() {
    use crate::model::{Instance, Shape, Table};
    let settings = Settings::default();
    let drives = [
        (Shape::Sawtooth, [0.0; 3], crate::model::NO_SLEW_LIMIT),
        (
            Shape::Trapezoid,
            [0.9, 0.05, 0.02],
            crate::model::NO_SLEW_LIMIT,
        ),
        (Shape::Trapezoid, [0.5, 0.0, 0.2], 3e4),
        (
            Shape::Table(Table::intern(&[
                [0.1, -0.5],
                [0.8, 1.0],
                [0.82, 0.2],
                [0.82, -0.3],
            ])),
            [0.0; 3],
            crate::model::NO_SLEW_LIMIT,
        ),
        (Shape::Sawtooth, [0.0; 3], 4e4),
    ];
    for (shape, [rise, hold, fall], slew) in drives {
        let mut inst = Instance::TABLE1;
        inst.axes[0].shape = shape;
        (inst.axes[0].rise, inst.axes[0].hold, inst.axes[0].fall) = (rise, hold, fall);
        inst.axes[0].slew_rate = slew;
        inst.axes[1].voltage = 40.0;
        inst.axes[1].frequency = 13.0;
        let single = crate::laws::karnopp::single::integrate::Coefficients::of(&inst, &settings);
        let s = crate::laws::karnopp::single::integrate::Coefficients::segments_of(&inst);
        assert_eq!(single.segments, s, "single, {shape:?}");
        let double = Coefficients::of(&inst, &settings);
        assert_eq!(
            double.segments,
            Coefficients::segments_of(&inst),
            "double, {shape:?}"
        );
    }
}
