//! Case `prony`: a step strain held constant must relax as the Prony series
//! α(t) = 1 − Σ α_i (1 − e^(−t/τ_i)).
//!
//! Every node of a neo-Hookean cube is prescribed (Ramp::Step) to a homogeneous 10 %
//! stretch at t = 0 and held; the system is stepped with `symplectic_euler` and the
//! reaction on the top face, R(t), is compared with R(0)·α(t). The incremental
//! scheme (DESIGN §1) is backward Euler in each internal variable, so R(t_n)/R(0) is
//! exactly 1 − Σ α_i (1 − B_i^n), B_i = τ_i/(Δt + τ_i) (checked to round-off), and
//! differs from α(t) by ≈ Σ α_i e^(−t/τ_i) t Δt/(2τ_i²) ≤ Σ α_i Δt/(2e·τ_i).

use super::plot::{draw, Chart, Mark, Series};
use super::{fmt_num, CaseReport, Options, Row};
use heml::mesh::generate::{box_mesh, HexSplit};
use heml::system::{relaxation, PronyTerm, Ramp, TimeStepPolicy};
use heml::{Params, Result, Vec3};

pub(crate) fn run(opts: &Options, report: &mut CaseReport) -> Result<()> {
    let terms = [PronyTerm::new(0.3, 0.1), PronyTerm::new(0.2, 1.0)];
    let (dt, t_end): (f64, f64) = if opts.quick { (2e-3, 1.0) } else { (1e-3, 4.0) };
    let mesh = box_mesh([0.1; 3], [2, 2, 2], HexSplit::Six)?;
    let all: Vec<usize> = (0..mesh.n_nodes()).collect();
    let top: Vec<usize> = all
        .iter()
        .copied()
        .filter(|&i| mesh.nodes()[i].z > 0.1 - 1e-9)
        .collect();
    let mut sys = heml::system(mesh)
        .material("neo_hookean", Params::from([("E", 1e4), ("nu", 0.3)]))?
        .prony(&terms)
        .prescribe_with(&all, |p| Vec3::new(0.0, 0.0, 0.1 * p.z), Ramp::Step)
        .time_step_policy(TimeStepPolicy::Ignore) // no free node: nothing to destabilise
        .build()?;
    let mut integrator = heml::integrator("symplectic_euler")?;
    let reaction = |sys: &heml::system::System| top.iter().map(|&i| sys.reactions()[i].z).sum::<f64>();
    sys.compute_forces()?;
    let r0 = reaction(&sys);
    let steps = (t_end / dt).round() as usize;
    let (mut err_cont, mut err_disc) = ((0.0, 0.0), 0.0_f64);
    let mut pts = vec![(0.0, 1.0)];
    for n in 1..=steps {
        integrator.step(&mut sys, dt)?;
        sys.compute_forces()?; // advances the internal variables to the new time
        let ratio = reaction(&sys) / r0;
        let t = sys.time();
        let disc = 1.0
            - terms
                .iter()
                .map(|p| p.alpha * (1.0 - (p.tau / (dt + p.tau)).powi(n as i32)))
                .sum::<f64>();
        err_disc = err_disc.max((ratio - disc).abs());
        let e = (ratio - relaxation(&terms, t)).abs();
        if e > err_cont.0 {
            err_cont = (e, t);
        }
        if n % (steps / 200).max(1) == 0 {
            pts.push((t, ratio));
        }
    }
    report.notes.push(format!(
        "terms (alpha, tau) = {:?}, dt = {dt} s, {steps} steps, R(0) = {} N",
        terms.iter().map(|p| (p.alpha, p.tau)).collect::<Vec<_>>(),
        fmt_num(r0)
    ));
    let bound: f64 = terms
        .iter()
        .map(|p| p.alpha * dt / (2.0 * std::f64::consts::E * p.tau))
        .sum();
    report.rows.push(Row::check(
        format!("R(t)/R(0) vs alpha(t), worst at t = {:.3} s", err_cont.1),
        fmt_num(relaxation(&terms, err_cont.1) + err_cont.0),
        fmt_num(relaxation(&terms, err_cont.1)),
        err_cont.0,
        // first-order scheme: the bound above, with 20 % margin
        1.2 * bound,
    ));
    report.rows.push(Row::check(
        "R(t_n)/R(0) vs exact discrete series 1 - sum a_i(1 - B_i^n)",
        "HEML".into(),
        "closed form".into(),
        err_disc,
        // same recurrence evaluated two ways: round-off only
        1e-12,
    ));
    let end = relaxation(&terms, t_end);
    report.rows.push(Row::check(
        format!("relaxed modulus ratio at t = {t_end} s"),
        fmt_num(pts.last().map_or(f64::NAN, |p| p.1)),
        fmt_num(end),
        (pts.last().map_or(f64::NAN, |p| p.1) - end).abs(),
        1.2 * bound,
    ));
    if let Some(path) = opts.plot_path("prony")? {
        let fine: Vec<(f64, f64)> = (0..=400)
            .map(|k| {
                let t = t_end * k as f64 / 400.0;
                (t, relaxation(&terms, t))
            })
            .collect();
        let chart = Chart::xy(
            "held 10 % step strain",
            "time (s)",
            "R(t) / R(0)",
            vec![
                Series::new("alpha(t) closed form", fine, Mark::Line),
                Series::new("HEML reaction", pts, Mark::Points),
            ],
        );
        draw(&path, "Prony relaxation", &[chart])?;
        report.plot = Some(path);
    }
    Ok(())
}
