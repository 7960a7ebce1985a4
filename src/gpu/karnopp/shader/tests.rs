//! The Karnopp shader source's tests: the prelude's literals, every
//! variant parsed, validated and written as SPIR-V, every WGSL file
//! mirroring its Rust file, the propagator unrolled, and no f64 division
//! or square root outside the prelude's helpers, and where a lane holds a
//! step.

use super::*;
use crate::gpu::mirrors::{assert_mirrors, defined_functions};

#[test]
fn prelude_literals_round_trip() {
    let max = format!("{:e}", f32::MAX as f64);
    assert_eq!(max.parse::<f64>().unwrap() as f32, f32::MAX);
    assert_eq!(format!("{:e}", f64::MAX).parse::<f64>().unwrap(), f64::MAX);
    for n in 1..=22u32 {
        let text = format!("{:e}", 1.0 / n as f64);
        assert_eq!(text.parse::<f64>().unwrap(), 1.0 / n as f64);
    }
}

#[test]
fn every_variant_parses_and_validates() {
    for variant in Variant::every() {
        if let Err(e) = parse_and_validate(variant) {
            panic!("{variant:?}: {e}");
        }
    }
}

/// wgpu hands Vulkan drivers naga's SPIR-V: every variant must get
/// there (naga's writer rejects, for one, a pointer to a member of a
/// struct behind a pointer parameter, which its validator accepts).
#[test]
fn every_variant_writes_spir_v() {
    for variant in Variant::every() {
        let (module, info) = parse_and_validate(variant).unwrap();
        let options = naga::back::spv::Options::default();
        let words = naga::back::spv::write_vec(&module, &info, &options, None)
            .unwrap_or_else(|e| panic!("{variant:?}: {e}"));
        assert!(words.len() > 1000, "{variant:?}: {} words", words.len());
    }
}

/// Every shader file (but the entry point) defines the functions of its
/// Rust mirror and only those, apart from the listed helpers that one
/// side needs and the other does not (with the reason).
#[test]
fn every_shader_file_mirrors_its_rust_file() {
    let shader_only = shader_only_functions();
    let cpu_only = cpu_only_functions();
    for (wgsl_name, rust_text) in rust_mirrors() {
        check_mirror(wgsl_name, rust_text, &shader_only, &cpu_only);
    }
}

/// Each shader file (but the entry point) with the text of its Rust
/// mirror.
fn rust_mirrors() -> [(&'static str, &'static str); 11] {
    [
        (
            "karnopp/arith.wgsl",
            include_str!("../../../laws/karnopp/integrate/arith.rs"),
        ),
        (
            "karnopp/coefficients.wgsl",
            include_str!("../../../laws/karnopp/integrate/coefficients.rs"),
        ),
        (
            "karnopp/flow.wgsl",
            include_str!("../../../laws/karnopp/integrate/flow.rs"),
        ),
        (
            "karnopp/drive.wgsl",
            include_str!("../../../laws/karnopp/integrate/drive.rs"),
        ),
        (
            "karnopp/segments.wgsl",
            include_str!("../../../laws/karnopp/integrate/drive.rs"),
        ),
        (
            "karnopp/events.wgsl",
            include_str!("../../../laws/karnopp/integrate/events.rs"),
        ),
        (
            "karnopp/step.wgsl",
            include_str!("../../../laws/karnopp/integrate/step.rs"),
        ),
        (
            "karnopp/advance.wgsl",
            include_str!("../../../laws/karnopp/integrate/mod.rs"),
        ),
        (
            "shared/measure.wgsl",
            include_str!("../../../laws/floor/measure.rs"),
        ),
        (
            "shared/phase.wgsl",
            include_str!("../../../laws/floor/phase.rs"),
        ),
        (
            "shared/variation.wgsl",
            include_str!("../../../laws/floor/variation.rs"),
        ),
    ]
}

/// The functions only the shader defines.
fn shader_only_functions() -> [&'static str; 19] {
    // Shader only: WGSL has no Option, closures, methods or
    // is_finite, and splits some expressions into functions.
    [
        "identity_propagator",
        "series_term",
        "theta",
        // No arrays indexed at run time: the event samples by selection,
        // and one function for an event of any kind at a sample.
        "event_sample",
        "kind_event",
        "hermite_good",
        "any_primary_event",
        "sample_direction_error",
        "is_finite",
        "is_finite2",
        // No generics: the V2 form of `two_sum`.
        "two_sum2",
        // No closures: `window_coefficient`'s cut test.
        "is_cut",
        // The drive's two forms (issue 59): a sawtooth's corners from its
        // coefficients, other waveforms' segments from their buffer; the
        // CPU has the segments' one form, which is both's arithmetic.
        "pass_sawtooth_corners",
        "segment_drive",
        "next_segments",
        "following",
        // `eval_flow`'s slider in stick and in slip, which the backward
        // travel's `variation.wgsl` also reads (issue 59).
        "stuck_slider",
        "slip_slider",
        // No closures: the velocity's Hermite at s (`hermite_extremum`'s
        // `value`).
        "cubic_value",
    ]
}

/// The functions only the Rust mirrors define.
fn cpu_only_functions() -> [&'static str; 59] {
    // CPU only: constructors, the observer of trajectories (its `step`
    // method and `StepMotion`), the whole run (stoppable, also from a
    // state the f64 shader left) and its result, Rust's rounding and
    // the sample array.
    [
        "new",
        "default",
        // The coefficients in a precision (computed on the host), also
        // of a replica, and 1 / n, which the prelude generates for the
        // shader.
        "of",
        "of_replica",
        "new_replica",
        // Its parts: the mechanism, the drives, the steps and the
        // measurement.
        "set_mechanism",
        "set_drive",
        "set_steps",
        "set_measurement",
        "rounded",
        // The drive's segments (issue 59), made on the host (the shader
        // reads a sawtooth's from its coefficients, `layout::packed`, and
        // other waveforms' from their buffer, `layout::segment_buffer`).
        "segments_of",
        "is_sawtooth",
        "current_segments",
        "first_corner",
        "inverse_integer",
        "run_instance",
        "run_instance_until",
        "continue_until",
        "continue_instance_until",
        "displacement",
        "advance_observed",
        "step",
        "length",
        "end",
        "positions_at",
        // What the backward travel reads of a step (CPU only, issue 59:
        // `laws::karnopp::variation`), and the observer's period end.
        "start",
        "sample",
        "propagator",
        "compose",
        "rate",
        "stuck",
        "drift",
        "oscillator",
        "ringing_energy",
        // `measure::estimate` in two parts, MSER's cut and the estimate
        // from a cut, so that the backward travel's estimate takes the
        // step's cut (the shader's `estimate` is both at once).
        "cut",
        "estimate_from",
        "round_half_even",
        "sample_flow",
        // The host's part of the measurement: the common period, the
        // first batch, the tolerances (folded into Coefficients).
        "common_period",
        "short_common_period",
        "decimal_common_period",
        "as_decimal",
        "gcd",
        "is_whole",
        // The host's phase ladder: each window length's three-gap
        // table and the levels that may stop a run.
        "gaps",
        "largest_gap",
        "spread",
        "ladder_on",
        "ladder",
        "first_batch_length",
        "beat_batch_length",
        "repeat_tolerances",
        // The host's join of a cycle split (the shader inlines it).
        "repeats",
        "wgsl_constants",
        // The host's fixed-point phase coefficients.
        "fixed_fraction_32",
        "fixed_fraction_64",
        // The variation kept elsewhere (a lane's entry, read back), a
        // replica's release and a cycle split's piece: the host's.
        "from_parts",
        "release",
        "piece_travel",
    ]
}

/// The text of the shader file `name`.
fn shader_text(name: &str) -> &'static str {
    let (_, text) = FILES.iter().find(|(n, _)| *n == name).unwrap();
    text
}

/// Asserts that shader file `wgsl_name` and its Rust mirror define the
/// same functions, apart from `shader_only` and `cpu_only`.
fn check_mirror(wgsl_name: &str, rust_text: &str, shader_only: &[&str], cpu_only: &[&str]) {
    let wgsl_text = shader_text(wgsl_name);
    let wgsl = defined_functions(wgsl_text);
    let cpu = defined_functions(rust_text);
    // The GPU's `advance` (with the loop limiter) lives beside its
    // entry point.
    let mut found = wgsl.clone();
    if wgsl_name == "karnopp/advance.wgsl" {
        found.extend(defined_functions(shader_text("karnopp/entry.wgsl")));
    }
    // Pairs of files that mirror one Rust file together: the drive's (a
    // waveform variant's segments beside the sawtooth's corners), and
    // the floor's variation (`follow`, and the pieces only Karnopp
    // carries).
    let pairs = [
        ["karnopp/drive.wgsl", "karnopp/segments.wgsl"],
        ["shared/variation.wgsl", "shared/pieces.wgsl"],
    ];
    for pair in pairs {
        if let Some(k) = pair.iter().position(|&n| n == wgsl_name) {
            found.extend(defined_functions(shader_text(pair[1 - k])));
        }
    }
    assert_mirrors(wgsl_name, &wgsl, &found, &cpu, (shader_only, cpu_only));
}

/// The propagator's Taylor series is unrolled in the shader: one term
/// per constant the Rust loop runs over.
#[test]
fn the_shader_unrolls_every_propagator_term() {
    let (_, flow) = FILES
        .iter()
        .find(|(n, _)| *n == "karnopp/flow.wgsl")
        .unwrap();
    let terms = flow.matches("series_term(&s, t * INVERSE_").count();
    assert_eq!(terms as u32, TAYLOR_TERMS);
}

/// NVIDIA's compiler rejects f64 division and square root in this
/// shader, so the f64 variant has none outside the f32-free helpers
/// (which build them from inverseSqrt and fma).
#[test]
fn the_f64_shader_neither_divides_nor_takes_square_roots() {
    let variant = Variant {
        precision: Precision::F64,
        loop_limiter: false,
        parts: Parts::ALL,
    };
    let (module, info) = parse_and_validate(variant).unwrap();
    let is_f64 = |ty: &naga::TypeInner| {
        ty.scalar()
            .is_some_and(|s| s.kind == naga::ScalarKind::Float && s.width == 8)
    };
    let mut checked = 0;
    let functions = module.functions.iter().map(|(h, f)| (f, &info[h])).chain(
        module
            .entry_points
            .iter()
            .enumerate()
            .map(|(i, e)| (&e.function, info.get_entry_point(i))),
    );
    for (f, fi) in functions {
        let name = f.name.as_deref().unwrap_or("?");
        for (handle, expr) in f.expressions.iter() {
            let float = is_f64(fi[handle].ty.inner_with(&module.types));
            match expr {
                naga::Expression::Binary {
                    op: naga::BinaryOperator::Divide,
                    ..
                } if float => panic!("{name} divides in f64"),
                naga::Expression::Math {
                    fun: naga::MathFunction::Sqrt,
                    ..
                } if float => panic!("{name} takes an f64 square root"),
                _ => {}
            }
            checked += 1;
        }
    }
    assert!(checked > 1000, "only {checked} expressions seen");
}

/// Only an f64 hardware lane holds a step in device memory: its own
/// entries of bindings 9 to 11 in the shader's layout of the flow, the
/// samples and the propagators, and its state read and written in place;
/// its source keeps no private copy and no `st.` or `(*st).` outside
/// comments. Every other variant binds none and keeps its copies.
#[test]
fn only_an_f64_hardware_lane_holds_a_step_in_device_memory() {
    let code = |v: Variant| -> String {
        source(v)
            .lines()
            .map(|l| l.split("//").next().unwrap_or(""))
            .collect::<Vec<_>>()
            .join("\n")
    };
    for v in Variant::every() {
        let src = code(v);
        if v.holds_in_memory() {
            assert_eq!(v.precision, Precision::F64);
            assert!(!v.loop_limiter);
            // The flow's 880 B: 480 B of the step's motion and 400 B the
            // backward travel's variation keeps in it (unused elsewhere).
            assert_eq!(per_lane(v), &[(9, 880), (10, 640), (11, 128)]);
            assert!(!src.contains("var<private> flow"), "{v:?}");
            // `(*st).` only as a call's argument, as in
            // `drive_force(*st).slope`.
            let derefs = src.match_indices("(*st).").all(|(at, _)| {
                src[..at]
                    .chars()
                    .next_back()
                    .is_some_and(|c| c.is_alphanumeric() || c == '_')
            });
            assert!(derefs, "{v:?}");
            assert!(!src.contains(" st.") && !src.contains("(st."), "{v:?}");
            assert!(src.contains("states[held].x_p"), "{v:?}");
            assert!(src.contains("flows[lane_slot].osc.w2"), "{v:?}");
        } else {
            assert!(per_lane(v).is_empty(), "{v:?}");
            assert!(src.contains("var<private> flow: Flow;"), "{v:?}");
            assert!(!src.contains("flows[lane_slot]"), "{v:?}");
        }
    }
}
