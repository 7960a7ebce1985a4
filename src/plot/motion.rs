//! The kinds of motion (`/maps/motion`, [`Motion`]) as pictures: a
//! categorical map of every 2-D slice of a grid (`motion*.png`, drawn by
//! `maps`), a labelled strip along a 1-D grid (`motion.png`); a points
//! scene names each point's kind under its bars (`bars`). Only files with
//! a kind somewhere get them ([`Data::motion_shown`]): a window measurement
//! decides none.

use std::path::Path;

use anyhow::Result;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::canvas::{LEGEND_WIDTH, font, save, swatch, title_block};
use super::colour::{FAILED, NOT_STEADY};
use super::heatmap::{MapLegend, heatmap};
use super::placement::{Placement, label_values};
use super::read::{AxisData, Data};
use super::text::{axis_title, short};
use crate::laws::status::STATUS_NOT_STEADY;
use crate::model::motion::Motion;

/// What one cell of a motion picture shows: the kind of motion the steady
/// measurement found, or why the instance has none.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum MotionClass {
    /// The kind stored for an instance with status 0.
    Kind(Motion),
    /// A refined map's interpolated value: nothing was integrated there.
    Inferred,
    /// Status 6: ran to max_cycles without a verdict.
    NotSteady,
    /// Any other non-zero status.
    Failed,
}

impl MotionClass {
    /// Every class, in legend order: the kinds a verdict decides, then the
    /// reasons for none.
    pub(super) const ALL: [MotionClass; 8] = [
        MotionClass::Kind(Motion::Periodic),
        MotionClass::Kind(Motion::QuasiPeriodic),
        MotionClass::Kind(Motion::Irregular),
        MotionClass::Kind(Motion::Multistable),
        MotionClass::Kind(Motion::Undetermined),
        MotionClass::Inferred,
        MotionClass::NotSteady,
        MotionClass::Failed,
    ];

    /// The class of an instance of kind `motion`, `status` (as `read`
    /// gives it: a value that is not finite counts as failed) and whether
    /// a refinement inferred its value.
    pub(super) fn classify(motion: Motion, status: u32, inferred: bool) -> MotionClass {
        match status {
            0 if inferred => MotionClass::Inferred,
            0 => MotionClass::Kind(motion),
            STATUS_NOT_STEADY => MotionClass::NotSteady,
            _ => MotionClass::Failed,
        }
    }

    /// Whether the legend lists it even where no instance has it: the
    /// kinds a verdict decides, so that a count of 0 is read as none found.
    fn always_listed(self) -> bool {
        matches!(
            self,
            MotionClass::Kind(Motion::Periodic | Motion::QuasiPeriodic | Motion::Irregular)
        )
    }

    /// Its colour: blue locks, a green quasi-periodic sea, orange
    /// irregular motion, and the greys of the other maps for instances
    /// without a value.
    pub(super) fn colour(self) -> RGBColor {
        match self {
            MotionClass::Kind(Motion::Periodic) => RGBColor(33, 102, 172),
            MotionClass::Kind(Motion::QuasiPeriodic) => RGBColor(90, 174, 97),
            MotionClass::Kind(Motion::Irregular) => RGBColor(230, 97, 1),
            MotionClass::Kind(Motion::Multistable) => RGBColor(118, 42, 131),
            MotionClass::Kind(Motion::Undetermined) => RGBColor(245, 235, 200),
            MotionClass::Inferred => RGBColor(238, 238, 238),
            MotionClass::NotSteady => NOT_STEADY,
            MotionClass::Failed => FAILED,
        }
    }

    /// Its legend text: the kind's `flag_meanings` name first.
    pub(super) fn describe(self) -> &'static str {
        match self {
            MotionClass::Kind(Motion::Periodic) => "periodic: the state repeats",
            MotionClass::Kind(Motion::QuasiPeriodic) => "quasi_periodic: smooth in phase",
            MotionClass::Kind(Motion::Irregular) => "irregular: batch means only",
            MotionClass::Kind(Motion::Multistable) => "multistable: replicas disagreed",
            MotionClass::Kind(Motion::Undetermined) => "undetermined: no verdict",
            MotionClass::Inferred => "not integrated (inferred)",
            MotionClass::NotSteady => "not steady (status 6)",
            MotionClass::Failed => "not computed (status ≠ 0, 6)",
        }
    }
}

/// The class of instance `k` of `data`, whose kinds are `motion`.
fn class_of(data: &Data, motion: &[Motion], k: usize) -> MotionClass {
    let inferred = data.inferred.as_ref().is_some_and(|m| m[k] == 1);
    MotionClass::classify(motion[k], data.status[k], inferred)
}

/// The legend of the instances `cells`: every class listed with its count
/// in brackets.
fn legend(data: &Data, motion: &[Motion], cells: &[usize]) -> Vec<(RGBColor, String)> {
    let mut counts = [0usize; MotionClass::ALL.len()];
    for &k in cells {
        let class = class_of(data, motion, k);
        if let Some(c) = MotionClass::ALL.iter().position(|&m| m == class) {
            counts[c] += 1;
        }
    }
    MotionClass::ALL
        .iter()
        .zip(counts)
        .filter(|(c, n)| *n > 0 || c.always_listed())
        .map(|(c, n)| (c.colour(), format!("{} ({n})", c.describe())))
        .collect()
}

/// The title lines every motion picture shares, after its first.
fn explanation() -> Vec<String> {
    vec![
        "periodic: the state repeats after a whole number of common drive periods (a lock); \
         quasi_periodic: the"
            .to_owned(),
        "increments are a smooth function of the faster drive's phase; irregular: neither \
         (only the batch means converged)."
            .to_owned(),
        "Counts of instances in brackets.".to_owned(),
    ]
}

/// Draws the motion map of one 2-D slice of a grid: instance `flat(i, j)`
/// at value i of `across` and value j of `up`; `cells` are the slice's
/// instances, `extra` the slice's title lines.
#[allow(clippy::too_many_arguments)]
pub(super) fn motion_map(
    path: &Path,
    data: &Data,
    motion: &[Motion],
    across: &AxisData,
    up: &AxisData,
    flat: &dyn Fn(usize, usize) -> usize,
    cells: &[usize],
    extra: &[String],
) -> Result<()> {
    let mut title = vec![format!(
        "{}: kind of motion the steady measurement found (/maps/motion)",
        data.name
    )];
    title.extend(explanation());
    title.extend(extra.iter().cloned());
    heatmap(
        path,
        &title,
        across,
        up,
        &|i, j| class_of(data, motion, flat(i, j)).colour(),
        &MapLegend::Categories(legend(data, motion, cells)),
    )
}

/// Width and height of the strip of a 1-D grid [px].
const STRIP_SIZE: (u32, u32) = (1100, 600);

/// Draws the motion strip of a 1-D grid: one coloured cell per value of
/// `axis`, placed as the line plots place them.
pub(super) fn motion_strip(
    path: &Path,
    data: &Data,
    motion: &[Motion],
    axis: &AxisData,
) -> Result<()> {
    let mut title = vec![format!(
        "{}: kind of motion the steady measurement found against {} (/maps/motion)",
        data.name, axis.key
    )];
    title.extend(explanation());
    let cells: Vec<usize> = (0..axis.values.len()).collect();
    let items = legend(data, motion, &cells);
    save(path, STRIP_SIZE, |root| {
        let body = title_block(root, &title)?;
        let (left, right) = body.split_horizontally(STRIP_SIZE.0 - LEGEND_WIDTH);
        let place = Placement::of(&axis.values);
        let edges = place.edges(&axis.values);
        let lo = edges.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = edges.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let mut chart = ChartBuilder::on(&left)
            .margin(15)
            .x_label_area_size(60)
            .y_label_area_size(20)
            .build_cartesian_2d(lo..hi, 0.0..1.0)?;
        let fx = move |c: &f64| short(place.value(*c));
        chart
            .configure_mesh()
            .disable_mesh()
            .disable_y_axis()
            .x_desc(axis_title(&axis.key, &axis.units))
            .x_labels(if place.log { 0 } else { 10 })
            .x_label_formatter(&fx)
            .label_style(font(15))
            .axis_desc_style(font(17))
            .draw()?;
        if place.log {
            for v in label_values(&axis.values) {
                let (x, y) = chart.backend_coord(&(place.place(v), 0.0));
                root.draw(&PathElement::new(vec![(x, y), (x, y + 5)], BLACK))?;
                root.draw_text(
                    &short(v),
                    &font(15).pos(Pos::new(HPos::Center, VPos::Top)),
                    (x, y + 8),
                )?;
            }
        }
        chart.draw_series(cells.iter().map(|&k| {
            Rectangle::new(
                [(edges[k], 0.0), (edges[k + 1], 1.0)],
                class_of(data, motion, k).colour().filled(),
            )
        }))?;
        for (k, (c, text)) in items.iter().enumerate() {
            swatch(&right, 0, 30 + 30 * k as i32, *c, text)?;
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_instance_shows_its_kind_only_when_it_finished_and_was_integrated() {
        for kind in Motion::ALL {
            assert_eq!(
                MotionClass::classify(kind, 0, false),
                MotionClass::Kind(kind)
            );
            assert_eq!(MotionClass::classify(kind, 0, true), MotionClass::Inferred);
            assert_eq!(
                MotionClass::classify(kind, STATUS_NOT_STEADY, false),
                MotionClass::NotSteady
            );
            assert_eq!(MotionClass::classify(kind, 1, true), MotionClass::Failed);
            assert_eq!(
                MotionClass::classify(kind, u32::MAX, false),
                MotionClass::Failed
            );
        }
        // Every class has its own colour and text; each kind's text starts
        // with its flag_meanings name.
        for (i, a) in MotionClass::ALL.iter().enumerate() {
            for b in &MotionClass::ALL[i + 1..] {
                assert_ne!(a.colour(), b.colour(), "{a:?} {b:?}");
                assert_ne!(a.describe(), b.describe());
            }
            if let MotionClass::Kind(kind) = a {
                assert!(a.describe().starts_with(kind.name()), "{a:?}");
            }
        }
        for kind in Motion::ALL {
            assert!(MotionClass::ALL.contains(&MotionClass::Kind(kind)));
        }
    }
}
