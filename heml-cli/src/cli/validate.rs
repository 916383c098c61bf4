//! `heml validate`: the seed papers' validation cases, as a pass/fail table with
//! errors and tolerances, and one PNG plot per case.

use heml_validation::{self as validation, Options, Status};
use std::path::PathBuf;

/// Arguments of `heml validate`.
#[derive(clap::Args, Debug)]
pub struct ValidateArgs {
    /// Run only this case (the list below comes from the validation crate's table of
    /// cases, so it names every case the binary has).
    #[arg(long, value_name = "NAME",
          value_parser = clap::builder::PossibleValuesParser::new(validation::CASES.iter().map(|c| c.name)))]
    pub case: Option<String>,
    /// Folder for the PNG plots.
    #[arg(long, value_name = "DIR", default_value = "heml-validation-output")]
    pub out: PathBuf,
    /// Reduced resolution and shorter runs (as in the test suite).
    #[arg(long)]
    pub quick: bool,
    /// Folder of the shared meshes (default: $HEML_MESHES, then ../shared/meshes).
    #[arg(long, value_name = "DIR")]
    pub meshes: Option<PathBuf>,
}

/// Runs the cases, prints the table, fails when any check fails.
pub fn run(args: ValidateArgs) -> heml::Result<()> {
    let opts = Options {
        quick: args.quick,
        out_dir: Some(args.out),
        meshes: args.meshes,
    };
    let names: Vec<&str> = match &args.case {
        Some(name) => vec![validation::find_case(name)?.name],
        None => validation::CASES.iter().map(|c| c.name).collect(),
    };
    let mut reports = Vec::new();
    for name in names {
        eprintln!("validate: running {name} ...");
        let r = validation::run_case(name, &opts)?;
        eprintln!("validate: {name} done in {:.1} s", r.seconds);
        reports.push(r);
    }
    out!("{}", validation::format_table(&reports));
    let count = |s: Status| {
        reports
            .iter()
            .flat_map(|r| &r.rows)
            .filter(|row| row.status == s)
            .count()
    };
    let (pass, fail, skip) = (count(Status::Pass), count(Status::Fail), count(Status::Skip));
    let total: f64 = reports.iter().map(|r| r.seconds).sum();
    outln!("\n{pass} passed, {fail} failed, {skip} skipped ({total:.1} s)");
    if fail > 0 {
        return Err(heml::HemlError::Numerical(format!("{fail} validation check(s) failed")));
    }
    Ok(())
}
