//! `heml bench --energy`: a law declared at run time against the compiled law,
//! per tet, on one mesh, one thread, timed round-robin.

use super::bench::{median, median_ratio, time_round_robin, tissue_params, BenchArgs, Case};
use super::info::parse_params;
use heml::mesh::generate::box_of_about;
use heml::prelude::*;
use heml::RuntimeLaw;
use heml_validation::fixtures::{renumbered_at_load, smooth_deformation as deformed};

/// Times the HEML and P1 fields of `--law` and of `energy` (whose parameters are
/// `--param`, else `--law`'s values by name).
pub fn run(args: &BenchArgs, energy: &str, pool: &rayon::ThreadPool) -> heml::Result<()> {
    let entry = heml::find_material(&args.law)?;
    let compiled = entry.instantiate(&tissue_params(entry)?)?;
    if compiled.kind() != heml::law::LawKind::Invariant {
        return Err(HemlError::Invalid(format!(
            "--energy is compared with an invariant law; '{}' is a link law",
            entry.name
        )));
    }
    let params = if args.params.is_empty() {
        let mut p = Params::new();
        for (info, v) in compiled.param_info().iter().zip(compiled.param_values()) {
            p.set(info.name, v);
        }
        p
    } else {
        parse_params(&args.params)?
    };
    let runtime = RuntimeLaw::from_energy(energy, &params)?;
    let mesh = match &args.mesh {
        Some(path) => heml::io::read_mesh(path)?.0,
        None => box_of_about(args.tets)?,
    };
    let mesh = renumbered_at_load(&mesh)?;
    let x = deformed(&mesh);
    let n_tets = mesh.n_tets();
    let inner = (2_000_000 / n_tets.max(1)).clamp(1, 1000);
    let repeats = args.repeats.max(1);
    let opts = ForceOptions::default();
    let laws: [(&str, &dyn Material); 2] = [("compiled", compiled.as_ref()), ("runtime", &runtime)];
    let mut fields = Vec::new();
    for (_, law) in laws {
        fields.push(law.force_field(&mesh, None, &opts)?);
        if let Some(f) = law.fem_field(&mesh, None, &opts)? {
            fields.push(f);
        }
    }
    // the anti-locking patch fields: compiled, runtime along dilations, runtime with U
    let declared = match &args.volumetric_energy {
        Some(u) => Some(runtime.with_volumetric_energy(u)?),
        None => None,
    };
    if let Some(declared) = &declared {
        let patch = heml::law::Volumetric::patch(args.patch_size);
        for law in [compiled.as_ref(), &runtime as &dyn Material, declared] {
            fields.push(law.with_volumetric(patch)?.force_field(&mesh, None, &opts)?);
        }
    }
    let cases: Vec<Case> = fields
        .iter()
        .map(|f| Case::forces(pool, f.as_ref(), &x, inner, true))
        .collect();
    outln!("mesh: {} tets   law: {}   energy: {energy}", n_tets, entry.name);
    outln!("1 thread, {repeats} × {inner} calls (medians), tape: {} ops", {
        let o = runtime.op_count();
        o.add + o.mul + o.div + o.func
    });
    let samples = time_round_robin(&cases, repeats)?;
    let ns = |s: &[f64]| median(&mut s.to_vec()) / n_tets as f64 * 1e9;
    // the range of the samples, as min–max ns/tet
    let range = |s: &[f64]| {
        let per_tet = |t: f64| t / n_tets as f64 * 1e9;
        let (lo, hi) = s
            .iter()
            .fold((f64::INFINITY, 0.0_f64), |(lo, hi), &t| (lo.min(t), hi.max(t)));
        format!("{:.0}–{:.0}", per_tet(lo), per_tet(hi))
    };
    outln!(
        "{:<10} {:>12} {:>12} {:>12} {:>12}",
        "",
        "HEML ns/tet",
        "(range)",
        "P1 ns/tet",
        "(range)"
    );
    for (name, k) in [("compiled", 0), ("runtime", 2)] {
        outln!(
            "{:<10} {:>12.2} {:>12} {:>12.2} {:>12}",
            name,
            ns(&samples[k]),
            range(&samples[k]),
            ns(&samples[k + 1]),
            range(&samples[k + 1])
        );
    }
    outln!(
        "runtime / compiled: HEML {:.2}×, P1 {:.2}× (medians of the per-round ratios)",
        median_ratio(&samples[2], &samples[0]),
        median_ratio(&samples[3], &samples[1])
    );
    if let Some(u) = args.volumetric_energy.as_deref() {
        outln!();
        outln!(
            "patch volumetric term (k = {}), volumetric energy: {u}",
            args.patch_size
        );
        for (name, k) in [
            ("compiled (its declared U, if any)", 4),
            ("runtime, U along dilations", 5),
            ("runtime, declared U", 6),
        ] {
            outln!(
                "{:<34} {:>8.2} ns/tet ({}), {:.2}× the compiled law's element field",
                name,
                ns(&samples[k]),
                range(&samples[k]),
                median_ratio(&samples[k], &samples[0])
            );
        }
        outln!(
            "declared U / along dilations: {:.2}× (median of the per-round ratios)",
            median_ratio(&samples[6], &samples[5])
        );
    }
    Ok(())
}
