//! LuGre's shader source's tests: the source parsed, validated and
//! written as SPIR-V, its literals, every WGSL file mirroring its Rust
//! file, and no f64 division or square root in the fused arithmetic.

use super::*;
use crate::gpu::lugre::{HARDWARE_WORKGROUP_SIZE, SOFTWARE_WORKGROUP_SIZE};
use crate::gpu::mirrors::{assert_mirrors, defined_functions};

#[test]
fn the_shader_parses_validates_and_writes_spir_v() {
    let shapes = Form::ALL.into_iter().flat_map(|form| {
        [
            (SOFTWARE_WORKGROUP_SIZE, Arithmetic::Native, form),
            (HARDWARE_WORKGROUP_SIZE, Arithmetic::Fused, form),
        ]
    });
    for (size, arithmetic, form) in shapes {
        let (module, info) =
            parse_and_validate(size, arithmetic, form).unwrap_or_else(|e| panic!("{e}"));
        let options = naga::back::spv::Options::default();
        let words = naga::back::spv::write_vec(&module, &info, &options, None)
            .unwrap_or_else(|e| panic!("{e}"));
        assert!(words.len() > 1000);
    }
}

/// Literals read back as the values they were written from.
#[test]
fn prelude_literals_round_trip() {
    for v in EXP_TAYLOR
        .iter()
        .chain(&EXP_HALVINGS)
        .chain(A.iter().flatten())
        .chain(C.iter().flatten())
        .chain(&[EXP_LN2_HI, EXP_LN2_LO, f64::MIN_POSITIVE, SMALLEST_STEP])
    {
        assert_eq!(lit(*v).parse::<f64>().unwrap(), *v);
    }
}

/// `model.wgsl` and `rodas.wgsl` define the functions of their Rust
/// files and only those, apart from the listed ones.
#[test]
fn the_shader_files_mirror_their_rust_files() {
    let rust = [
        (
            "lugre/model.wgsl",
            include_str!("../../../laws/lugre/model.rs"),
        ),
        (
            "lugre/rodas.wgsl",
            include_str!("../../../laws/lugre/rodas.rs"),
        ),
    ];
    // Shader only: WGSL has no exp, hypot, powf or is_finite (their
    // CPU mirrors are in this file), and no methods: `solve_lu` is
    // `Lu::solve` (`solve` is `W::solve`'s name).
    let shader_only = [
        "keep",
        "two_sum",
        "split",
        "two_prod",
        "exp_nonpositive",
        "hypot",
        "hypot_kernel",
        "is_finite",
        "fourth_root",
        "solve_lu",
        // The bodies of the CPU's loops over the axes and the reduced
        // rows, called with literal indices (no array indexed at run
        // time once inlined).
        "rhs_axis",
        "jacobian_axis",
        "jacobian_pair",
        "ddz_dvr",
        "w_row",
        "reduced_entry",
        // The end of `Corners::piece_at`'s piece, or the sawtooth's, that
        // `Clock::next_corner` reads inline.
        "cycle_corner",
        // Rodas4's stages and coefficients by switches.
        "stage_a",
        "stage_c",
        "pick",
    ];
    // CPU only: `Model::new`, `Clock::of` and `cycles_per_period`,
    // which the host computes (`Params::of`; a lane's `begin_period`
    // takes the clock from the cycles per period).
    // Written out by the host (`factor_source`), not in rodas.wgsl.
    let cpu_only = ["new", "of", "cycles_per_period", "factor"];
    for (wgsl_name, rust_text) in rust {
        let (_, wgsl_text) = FILES.iter().find(|(n, _)| *n == wgsl_name).unwrap();
        let wgsl = defined_functions(wgsl_text);
        let cpu = defined_functions(rust_text);
        let lists = (&shader_only[..], &cpu_only[..]);
        assert_mirrors(wgsl_name, &wgsl, &wgsl, &cpu, lists);
    }
}

/// NVIDIA's compiler rejects f64 division and square roots
/// (`crate::gpu::prelude`): the hardware variant has none but in the
/// floor prelude's helpers; the software one divides natively.
#[test]
fn the_fused_shader_neither_divides_nor_takes_square_roots() {
    let count = |arithmetic, form| {
        let (module, info) = parse_and_validate(HARDWARE_WORKGROUP_SIZE, arithmetic, form).unwrap();
        let mut found = 0;
        for (handle, f) in module.functions.iter() {
            let fi = &info[handle];
            for (e, expr) in f.expressions.iter() {
                let is_f64 = fi[e]
                    .ty
                    .inner_with(&module.types)
                    .scalar()
                    .is_some_and(|s| s.kind == naga::ScalarKind::Float && s.width == 8);
                let op = matches!(
                    expr,
                    naga::Expression::Binary {
                        op: naga::BinaryOperator::Divide,
                        ..
                    } | naga::Expression::Math {
                        fun: naga::MathFunction::Sqrt,
                        ..
                    }
                );
                found += usize::from(op && is_f64);
            }
        }
        found
    };
    for form in Form::ALL {
        assert_eq!(count(Arithmetic::Fused, form), 0);
        assert!(count(Arithmetic::Native, form) >= 2);
    }
}

/// The hardware variant reads its parameters where used: no `model.`
/// outside comments, no private copy; `docs/model.md` in a comment is
/// left as it is.
#[test]
fn the_hardware_variant_reads_its_parameters_where_used() {
    for form in Form::ALL {
        let src = source(HARDWARE_WORKGROUP_SIZE, Arithmetic::Fused, form);
        let code: String = src
            .lines()
            .map(|l| l.split("//").next().unwrap_or(""))
            .collect::<Vec<_>>()
            .join("\n");
        assert!(!code.contains(" model.") && !code.contains("(model."));
        assert!(!code.contains("var<private> model"));
        assert!(code.contains("models[held].stiffness"));
        assert_eq!(code.contains("models[held].corner_first"), form.waveform());
    }
    assert_eq!(
        read_where_used("x = model.a; // docs/model.md\nmodels.b"),
        "x = models[held].a; // docs/model.md\nmodels.b"
    );
    let software = source(SOFTWARE_WORKGROUP_SIZE, Arithmetic::Native, Form::Sawtooth);
    assert!(software.contains("var<private> model: Model;"));
}
