//! The layout a review recording opens with: an overview tab (map, local 3D view and
//! the criteria), a sensors tab and a DISUPT tab (tables and sensitivity maps).

use rerun::blueprint::{
    Blueprint, Grid, Horizontal, MapView, Spatial2DView, Spatial3DView, Tabs, TensorView,
    TextDocumentView, TimePanel, TimeSeriesView, Vertical,
};

use crate::paths::*;
use crate::review::Review;

fn plot(name: &str, origin: &str) -> TimeSeriesView {
    TimeSeriesView::new(name).with_origin(origin)
}

/// The blueprint of `review`'s recording.
pub fn review_blueprint(review: &Review) -> Blueprint {
    let overview = Horizontal::new([
        Vertical::new([
            MapView::new("Map").with_origin("map").into(),
            Spatial3DView::new("Local ENU [m]")
                .with_origin(WORLD)
                .into(),
        ])
        .into(),
        Vertical::new([
            plot("Pitch: gyro vs accelerometer", PLOT_PITCH).into(),
            plot("Roll: gyro vs accelerometer", PLOT_ROLL).into(),
            plot("ΔΘ, ΔΦ and Kalman estimates", PLOT_RESIDUALS).into(),
            plot("Kryt1 (cumulative)", PLOT_KRYT1).into(),
        ])
        .into(),
    ])
    .with_name("Overview");
    let sensors = Grid::new([
        plot("Odometer speed", PLOT_SPEED).into(),
        plot("Acceleration terms", PLOT_ACCEL_TERMS).into(),
        plot("IMU rates (raw increments)", PLOT_IMU_GYRO).into(),
        plot("IMU specific force (raw increments)", PLOT_IMU_ACCEL).into(),
    ])
    .with_name("Sensors");
    let mut disupt_views = vec![
        Vertical::new([
            TextDocumentView::new("DISUPT tables")
                .with_origin(DISUPT_TABLES)
                .into(),
            plot("Corrected route 1σ", PLOT_ROUTE_SIGMA).into(),
        ])
        .into(),
    ];
    match review.sweep.as_ref().map(|s| s.axes.len()) {
        Some(1) => disupt_views.push(
            Vertical::new([
                Spatial2DView::new("Kryt1 sweep")
                    .with_origin(format!("{SENSITIVITY}/kryt1"))
                    .into(),
                Spatial2DView::new("Kryt2 sweep")
                    .with_origin(format!("{SENSITIVITY}/kryt2"))
                    .into(),
            ])
            .into(),
        ),
        Some(2) => disupt_views.push(
            Vertical::new([
                TensorView::new("Kryt1 map")
                    .with_origin(format!("{SENSITIVITY}/kryt1"))
                    .into(),
                TensorView::new("Kryt2 map")
                    .with_origin(format!("{SENSITIVITY}/kryt2"))
                    .into(),
            ])
            .into(),
        ),
        _ => {}
    }
    let disupt = Horizontal::new(disupt_views).with_name("DISUPT");
    let about = TextDocumentView::new("Read me").with_origin(README);
    Blueprint::new(Tabs::new([
        overview.into(),
        sensors.into(),
        disupt.into(),
        about.into(),
    ]))
    .with_time_panel(TimePanel::new().with_timeline(TIME))
}
