//! The control points across a campaign's runs. A point surveyed wrong is left out of the
//! joint fit, or called inconsistent, in every run that visits it, where a fault of one
//! run (its mark, its stop) shows in that run alone: `campaign.md` lists the points left
//! out or called inconsistent in any run, with how many runs visit them and how often.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use unz_formats::manifest::ControlPoint;
use unz_stages::disupt::{Holdout, median_max};

/// A surveyed point: its id and its position to 1e-7° (about a centimetre).
type Key = (u32, i64, i64);

/// What the runs said of one point.
#[derive(Debug, Clone, Default, PartialEq)]
struct Across {
    latitude_deg: f64,
    longitude_deg: f64,
    /// Runs whose joint fit's hold-out has the point.
    runs: usize,
    /// Of them, those that left it out.
    left_out: usize,
    /// Those that called it inconsistent (left out or not).
    inconsistent: usize,
    /// Its hold-out error in each, m.
    errors_m: Vec<f64>,
}

/// The control points of a campaign's runs, gathered run by run.
#[derive(Debug, Default)]
pub struct PointsAcross {
    points: BTreeMap<Key, Across>,
}

impl PointsAcross {
    /// Adds a run: its manifest's `points` and its joint fit's `holdout` (points without
    /// a surveyed position in the manifest are skipped). A point the run came back to
    /// counts once for the run (left out, or inconsistent, at any visit), with each
    /// visit's error.
    pub fn add(&mut self, points: &[ControlPoint], holdout: &[Holdout]) {
        let mut of_run: BTreeMap<Key, (Across, bool, bool)> = BTreeMap::new();
        for h in holdout {
            let Some(p) = points.iter().find(|p| p.id == h.id) else {
                continue;
            };
            let (lat, lon) = (p.position.latitude_deg, p.position.longitude_deg);
            let key = (h.id, (lat * 1e7).round() as i64, (lon * 1e7).round() as i64);
            let (a, left_out, inconsistent) = of_run.entry(key).or_insert_with(|| {
                let a = Across {
                    latitude_deg: lat,
                    longitude_deg: lon,
                    ..Across::default()
                };
                (a, false, false)
            });
            *left_out |= h.excluded;
            *inconsistent |= h.inconsistent;
            a.errors_m.push(h.dx_m.hypot(h.dy_m));
        }
        for (key, (run, left_out, inconsistent)) in of_run {
            let a = self.points.entry(key).or_insert_with(|| Across {
                errors_m: Vec::new(),
                ..run.clone()
            });
            a.runs += 1;
            a.left_out += usize::from(left_out);
            a.inconsistent += usize::from(inconsistent);
            a.errors_m.extend(run.errors_m);
        }
    }

    /// `campaign.md`'s section, when a point was left out or called inconsistent in any
    /// run: those points (the most left out first), with how many runs visit them.
    pub fn markdown(&self) -> Option<String> {
        let mut shown: Vec<(&Key, &Across)> = self
            .points
            .iter()
            .filter(|(_, a)| a.left_out + a.inconsistent > 0)
            .collect();
        if shown.is_empty() {
            return None;
        }
        shown.sort_by(|x, y| {
            (y.1.left_out, y.1.inconsistent, y.1.runs)
                .cmp(&(x.1.left_out, x.1.inconsistent, x.1.runs))
                .then(x.0.cmp(y.0))
        });
        let mut md = String::from(
            "\n## Control points that disagree\n\nLeft out of the joint fit, or called \
             inconsistent with the rest of a run, in any run; a point surveyed wrong is so in \
             every run that visits it.\n\n| point | latitude [°] | longitude [°] | runs | left out \
             | inconsistent | hold-out median [m] | max [m] |\n|---|---|---|---|---|---|---|---|\n",
        );
        for ((id, ..), a) in shown {
            let Some((median, max)) = median_max(&mut a.errors_m.clone()) else {
                continue;
            };
            let _ = writeln!(
                md,
                "| {id} | {:.7} | {:.7} | {} | {} | {} | {median:.1} | {max:.1} |",
                a.latitude_deg, a.longitude_deg, a.runs, a.left_out, a.inconsistent,
            );
        }
        Some(md)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use unz_formats::manifest::Geodetic;

    fn point(id: u32, lat: f64) -> ControlPoint {
        ControlPoint {
            id,
            position: Geodetic {
                latitude_deg: lat,
                longitude_deg: 21.0,
                height_m: 100.0,
            },
            t_s: None,
        }
    }

    fn held(id: u32, error_m: f64, excluded: bool) -> Holdout {
        Holdout {
            id,
            t_s: 0.0,
            dx_m: error_m,
            dy_m: 0.0,
            sigma_north_m: None,
            sigma_east_m: None,
            error_sigma: None,
            inconsistent: excluded,
            excluded,
            apart: false,
        }
    }

    #[test]
    fn a_point_left_out_in_every_run_that_visits_it_is_listed_first() {
        let mut across = PointsAcross::default();
        assert_eq!(across.markdown(), None);
        // Three runs share points 1 and 6; a fourth has its own point 6 elsewhere.
        for _ in 0..3 {
            across.add(
                &[point(1, 52.0), point(6, 52.1)],
                &[held(1, 0.2, false), held(6, 10.0, true)],
            );
        }
        across.add(&[point(6, 50.0)], &[held(6, 0.3, false)]);
        // One run's fault at point 1, which it came back to: one run, both visits' errors.
        across.add(&[point(1, 52.0)], &[held(1, 4.0, true), held(1, 4.2, true)]);
        let md = across.markdown().unwrap();
        let rows: Vec<&str> = md.lines().filter(|l| l.starts_with("| ")).collect();
        assert_eq!(rows.len(), 3, "{md}");
        assert!(
            rows[1].starts_with("| 6 | 52.1000000 | 21.0000000 | 3 | 3 | 3 | 10.0 | 10.0 |"),
            "{md}"
        );
        assert!(
            rows[2].starts_with("| 1 | 52.0000000 | 21.0000000 | 4 | 1 | 1 | 0.2 | 4.2 |"),
            "{md}"
        );
    }
}
