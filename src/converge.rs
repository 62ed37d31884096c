//! Convergence measurements: error against a reference as a function of samples per
//! pixel and of seconds, averaged over independent seeds, written as CSV.
use crate::film::{Metrics, write_atomically};
use crate::{Error, Result};
use std::io::Write;
use std::path::Path;

/// One render's measurements.
#[derive(Clone, Debug)]
pub struct Run {
    pub integrator: String,
    pub spp: u32,
    pub seed: u64,
    pub seconds: f64,
    pub prepass_seconds: f64,
    pub metrics: Metrics,
}

/// The mean and standard error of the runs sharing an integrator and spp.
#[derive(Clone, Debug)]
pub struct Summary {
    pub integrator: String,
    pub spp: u32,
    pub runs: usize,
    pub mse: (f64, f64),
    pub rel_mse: (f64, f64),
    pub seconds: (f64, f64),
    pub prepass_seconds: f64,
}

/// Mean and standard error of the mean (0 for a single value).
#[must_use]
pub fn mean_and_se(x: &[f64]) -> (f64, f64) {
    let n = x.len() as f64;
    if x.is_empty() {
        return (f64::NAN, f64::NAN);
    }
    let m = x.iter().sum::<f64>() / n;
    if x.len() < 2 {
        return (m, 0.0);
    }
    let var = x.iter().map(|v| (v - m).powi(2)).sum::<f64>() / (n - 1.0);
    (m, (var / n).sqrt())
}

/// Groups runs by (integrator, spp), in first-seen order.
#[must_use]
pub fn summarise(runs: &[Run]) -> Vec<Summary> {
    let mut keys: Vec<(String, u32)> = Vec::new();
    for r in runs {
        if !keys.iter().any(|(i, s)| *i == r.integrator && *s == r.spp) {
            keys.push((r.integrator.clone(), r.spp));
        }
    }
    keys.into_iter()
        .map(|(integrator, spp)| {
            let group: Vec<&Run> = runs.iter().filter(|r| r.integrator == integrator && r.spp == spp).collect();
            let col = |f: &dyn Fn(&Run) -> f64| group.iter().map(|r| f(r)).collect::<Vec<f64>>();
            Summary {
                runs: group.len(),
                mse: mean_and_se(&col(&|r| r.metrics.mse)),
                rel_mse: mean_and_se(&col(&|r| r.metrics.rel_mse)),
                seconds: mean_and_se(&col(&|r| r.seconds)),
                prepass_seconds: mean_and_se(&col(&|r| r.prepass_seconds)).0,
                integrator,
                spp,
            }
        })
        .collect()
}

/// Writes the per-run and the summary CSVs into `dir` (created if needed), atomically.
fn io(p: &Path) -> impl Fn(std::io::Error) -> Error + '_ {
    move |e| Error::io(p, e)
}

pub fn write_csv(dir: &Path, runs: &[Run], summary: &[Summary]) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let path = dir.join("runs.csv");
    write_atomically(&path, |w| {
        writeln!(w, "integrator,spp,seed,seconds,prepass_seconds,mse,rel_mse").map_err(io(&path))?;
        for r in runs {
            writeln!(
                w,
                "{},{},{},{:.4},{:.4},{:.6e},{:.6e}",
                r.integrator, r.spp, r.seed, r.seconds, r.prepass_seconds, r.metrics.mse, r.metrics.rel_mse
            )
            .map_err(io(&path))?;
        }
        Ok(())
    })?;
    let path = dir.join("converge.csv");
    write_atomically(&path, |w| {
        writeln!(w, "integrator,spp,runs,mse,mse_se,rel_mse,rel_mse_se,seconds,seconds_se,prepass_seconds")
            .map_err(io(&path))?;
        for s in summary {
            writeln!(
                w,
                "{},{},{},{:.6e},{:.6e},{:.6e},{:.6e},{:.4},{:.4},{:.4}",
                s.integrator,
                s.spp,
                s.runs,
                s.mse.0,
                s.mse.1,
                s.rel_mse.0,
                s.rel_mse.1,
                s.seconds.0,
                s.seconds.1,
                s.prepass_seconds
            )
            .map_err(io(&path))?;
        }
        Ok(())
    })
}

/// Draws `mse_vs_spp` (the paper's Fig. 1) and `mse_vs_seconds` (equal time, pre-pass
/// included) into `dir`, each as PNG and SVG.
pub fn plot(dir: &Path, scene: &str, summary: &[Summary]) -> Result<()> {
    let mut names: Vec<&str> = Vec::new();
    for s in summary {
        if !names.contains(&s.integrator.as_str()) {
            names.push(&s.integrator);
        }
    }
    let series = |x: &dyn Fn(&Summary) -> f64| -> Vec<crate::plot::Series> {
        names
            .iter()
            .map(|n| crate::plot::Series {
                name: n.to_string(),
                points: summary.iter().filter(|s| s.integrator == *n).map(|s| (x(s), s.mse.0, s.mse.1)).collect(),
            })
            .collect()
    };
    crate::plot::log_log(
        &dir.join("mse_vs_spp"),
        &format!("{scene}: MSE vs samples per pixel"),
        "samples per pixel",
        "MSE",
        &series(&|s| s.spp as f64),
    )?;
    crate::plot::log_log(
        &dir.join("mse_vs_seconds"),
        &format!("{scene}: MSE vs render seconds"),
        "seconds (photon pass included)",
        "MSE",
        &series(&|s| s.seconds.0),
    )
}

/// How long one run took to reach a target MSE.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TimeToMse {
    /// Seconds, interpolated log–log between the last render above the target and the first
    /// at or below it (the first render's seconds if it is already below).
    pub seconds: f64,
    /// Samples per pixel of the first render at or below the target.
    pub spp: u32,
    /// False when `max_spp` was reached first (then `seconds` is that render's).
    pub reached: bool,
}

/// Doubles the sample count from 1 (`render(spp)` returns seconds and MSE of an independent
/// render) until the MSE is at most `target`, then interpolates `log seconds` against
/// `log MSE` between the last two renders.
pub fn time_to_mse(mut render: impl FnMut(u32) -> Result<(f64, f64)>, target: f64, max_spp: u32) -> Result<TimeToMse> {
    let mut previous: Option<(f64, f64)> = None;
    let mut spp = 1u32;
    loop {
        let (seconds, mse) = render(spp)?;
        if mse <= target {
            let seconds = match previous {
                Some((s0, m0)) if m0 > mse && mse > 0.0 && s0 > 0.0 && seconds > 0.0 => {
                    // Where the line through (ln m0, ln s0), (ln mse, ln s) meets ln target.
                    let f = (target.ln() - m0.ln()) / (mse.ln() - m0.ln());
                    (s0.ln() + f * (seconds.ln() - s0.ln())).exp()
                }
                _ => seconds,
            };
            return Ok(TimeToMse { seconds, spp, reached: true });
        }
        if spp >= max_spp {
            return Ok(TimeToMse { seconds, spp, reached: false });
        }
        previous = Some((seconds, mse));
        spp = (spp * 2).min(max_spp);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn time_to_mse_interpolates_log_log() {
        // MSE = 100/spp, seconds = spp/10: the target 10 is reached at 10 spp = 1 s exactly,
        // between the renders at 8 and 16 spp.
        let mut calls = Vec::new();
        let t = time_to_mse(
            |spp| {
                calls.push(spp);
                Ok((spp as f64 / 10.0, 100.0 / spp as f64))
            },
            10.0,
            1024,
        )
        .unwrap();
        assert_eq!(calls, [1, 2, 4, 8, 16]);
        assert!(t.reached && t.spp == 16 && (t.seconds - 1.0).abs() < 1e-9, "{t:?}");
        let capped = time_to_mse(|spp| Ok((spp as f64, 1.0)), 0.5, 4).unwrap();
        assert!(!capped.reached && capped.spp == 4);
    }

    #[test]
    fn mean_and_standard_error() {
        let (m, se) = mean_and_se(&[1.0, 2.0, 3.0, 4.0]);
        assert!((m - 2.5).abs() < 1e-12);
        // s² = 5/3, se = √(s²/4).
        assert!((se - (5.0f64 / 12.0).sqrt()).abs() < 1e-12);
        assert_eq!(mean_and_se(&[7.0]), (7.0, 0.0));
    }

    #[test]
    fn summaries_group_by_integrator_and_spp() {
        let run = |i: &str, spp, mse| Run {
            integrator: i.into(),
            spp,
            seed: 0,
            seconds: 1.0,
            prepass_seconds: 0.0,
            metrics: Metrics { mse, rel_mse: mse },
        };
        let s = summarise(&[run("a", 1, 2.0), run("a", 1, 4.0), run("b", 1, 1.0), run("a", 2, 1.0)]);
        assert_eq!(s.len(), 3);
        assert_eq!((s[0].integrator.as_str(), s[0].spp, s[0].runs), ("a", 1, 2));
        assert!((s[0].mse.0 - 3.0).abs() < 1e-12);
    }
}
