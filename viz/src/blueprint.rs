//! The layout a review recording opens with: an overview tab (map, local 3D view and
//! the criteria), a sensors tab and a DISUPT tab (tables and sensitivity maps).
//!
//! Written as blueprint archetypes directly rather than through rerun's blueprint builder:
//! the builder (rerun 0.36) cannot set a view's properties, and the time-series views need
//! their `TimeAxis` range set to the whole run (the default is ±30 s around the time
//! cursor; the paper's Fig. 1 is the cumulative Kryt1 over the run). Container and view ids
//! are derived from their place in the layout, so the blueprint is the same every time.

use rerun::external::re_log_types::{ApplicationId, BlueprintActivationCommand, LogMsg};
use rerun::external::re_sdk_types::blueprint::archetypes::{
    ContainerBlueprint, TimeAxis, TimePanelBlueprint, ViewBlueprint, ViewContents,
    ViewportBlueprint,
};
use rerun::external::re_sdk_types::blueprint::components::{
    ContainerKind, IncludedContent, QueryExpression, RootContainer, TimeRange, ViewClass,
};
use rerun::external::re_sdk_types::components::Name;
use rerun::external::re_sdk_types::datatypes;
use rerun::sink::{BufferedSink, MemorySinkStorage};
use rerun::{RecordingStream, RecordingStreamBuilder, RecordingStreamResult};

use crate::paths::*;
use crate::review::Review;

/// A container or a view of the layout.
#[derive(Debug, Clone, PartialEq)]
pub enum Node {
    /// Children side by side, stacked, in a grid or in tabs.
    Container {
        /// Horizontal, vertical, grid or tabs.
        kind: ContainerKind,
        /// Tab or title, when shown.
        name: Option<String>,
        /// What it holds, in order.
        children: Vec<Node>,
    },
    /// One view of the entities under `origin`.
    View {
        /// The viewer's view class (`TimeSeries`, `Map`, `3D`, `2D`, `Tensor`,
        /// `TextDocument`).
        class: &'static str,
        /// Title.
        name: String,
        /// Entity path the view shows (with everything below it).
        origin: String,
    },
}

fn view(class: &'static str, name: &str, origin: &str) -> Node {
    Node::View {
        class,
        name: name.to_owned(),
        origin: origin.to_owned(),
    }
}

fn plot(name: &str, origin: &str) -> Node {
    view("TimeSeries", name, origin)
}

fn container(kind: ContainerKind, name: Option<&str>, children: Vec<Node>) -> Node {
    Node::Container {
        kind,
        name: name.map(str::to_owned),
        children,
    }
}

/// The layout of `review`'s recording.
pub fn review_layout(review: &Review) -> Node {
    use ContainerKind::{Grid, Horizontal, Tabs, Vertical};
    let overview = container(
        Horizontal,
        Some("Overview"),
        vec![
            container(
                Vertical,
                None,
                vec![
                    view("Map", "Map", "map"),
                    view("3D", "Local ENU [m]", WORLD),
                ],
            ),
            container(
                Vertical,
                None,
                vec![
                    plot("Pitch: gyro vs accelerometer", PLOT_PITCH),
                    plot("Roll: gyro vs accelerometer", PLOT_ROLL),
                    plot("ΔΘ, ΔΦ and Kalman estimates", PLOT_RESIDUALS),
                    plot("Kryt1 (cumulative)", PLOT_KRYT1),
                ],
            ),
        ],
    );
    let sensors = container(
        Grid,
        Some("Sensors"),
        vec![
            plot("Odometer speed", PLOT_SPEED),
            plot("Acceleration terms", PLOT_ACCEL_TERMS),
            plot("IMU rates (raw increments)", PLOT_IMU_GYRO),
            plot("IMU specific force (raw increments)", PLOT_IMU_ACCEL),
        ],
    );
    let mut disupt = vec![container(
        Vertical,
        None,
        vec![
            view("TextDocument", "DISUPT tables", DISUPT_TABLES),
            plot("Corrected route 1σ", PLOT_ROUTE_SIGMA),
        ],
    )];
    let (kryt1, kryt2) = (
        format!("{SENSITIVITY}/kryt1"),
        format!("{SENSITIVITY}/kryt2"),
    );
    match review.sweep.as_ref().map(|s| s.axes.len()) {
        Some(1) => disupt.push(container(
            Vertical,
            None,
            vec![
                view("2D", "Kryt1 sweep", &kryt1),
                view("2D", "Kryt2 sweep", &kryt2),
            ],
        )),
        Some(2) => disupt.push(container(
            Vertical,
            None,
            vec![
                view("Tensor", "Kryt1 map", &kryt1),
                view("Tensor", "Kryt2 map", &kryt2),
            ],
        )),
        _ => {}
    }
    container(
        Tabs,
        None,
        vec![
            overview,
            sensors,
            container(Horizontal, Some("DISUPT"), disupt),
            view("TextDocument", "Read me", README),
        ],
    )
}

/// A stable id for the node at `place` (its indices from the root).
fn node_id(place: &str) -> [u8; 16] {
    let h = blake3::hash(format!("unz-review-blueprint/{place}").as_bytes());
    let mut id = [0u8; 16];
    id.copy_from_slice(&h.as_bytes()[..16]);
    id[6] = (id[6] & 0x0f) | 0x40; // the layout of a version-4 UUID
    id[8] = (id[8] & 0x3f) | 0x80;
    id
}

fn uuid_text(id: &[u8; 16]) -> String {
    let hex: String = id.iter().map(|b| format!("{b:02x}")).collect();
    format!(
        "{}-{}-{}-{}-{}",
        &hex[0..8],
        &hex[8..12],
        &hex[12..16],
        &hex[16..20],
        &hex[20..32]
    )
}

/// Blueprint path of the node at `place`.
fn node_path(node: &Node, place: &str) -> String {
    let kind = match node {
        Node::Container { .. } => "container",
        Node::View { .. } => "view",
    };
    format!("{kind}/{}", uuid_text(&node_id(place)))
}

/// Logs `node` (at `place`) and everything in it to the blueprint stream `bp`.
fn log_node(bp: &RecordingStream, node: &Node, place: &str) -> RecordingStreamResult<()> {
    let path = node_path(node, place);
    match node {
        Node::Container {
            kind,
            name,
            children,
        } => {
            let mut contents = Vec::with_capacity(children.len());
            for (i, child) in children.iter().enumerate() {
                let child_place = format!("{place}/{i}");
                log_node(bp, child, &child_place)?;
                contents.push(IncludedContent(node_path(child, &child_place).into()));
            }
            let mut arch = ContainerBlueprint::new(*kind).with_contents(contents);
            if let Some(name) = name {
                arch = arch.with_display_name(Name(name.clone().into()));
            }
            bp.log(path, &arch)
        }
        Node::View {
            class,
            name,
            origin,
        } => {
            bp.log(
                format!("{path}/ViewContents"),
                &ViewContents::new([QueryExpression("$origin/**".into())]),
            )?;
            bp.log(
                path.as_str(),
                &ViewBlueprint::new(ViewClass((*class).into()))
                    .with_display_name(Name(name.clone().into()))
                    .with_space_origin(origin.as_str()),
            )?;
            if *class == "TimeSeries" {
                // The whole run, whatever the time cursor.
                bp.log(
                    format!("{path}/TimeAxis"),
                    &TimeAxis::new().with_view_range(TimeRange(datatypes::TimeRange::EVERYTHING)),
                )?;
            }
            Ok(())
        }
    }
}

/// The blueprint messages of `layout` for an application `app_id`.
fn blueprint_messages(app_id: ApplicationId, layout: &Node) -> RecordingStreamResult<Vec<LogMsg>> {
    let (bp, storage) = RecordingStreamBuilder::new(app_id)
        .recording_id(uuid_text(&node_id("blueprint")))
        .blueprint()
        .batcher_config(crate::rrd_sink::IN_LOGGED_ORDER)
        .memory()?;
    // The viewer reads blueprints on this timeline, and no wall-clock one.
    crate::rrd_sink::without_wall_clock(&bp);
    bp.set_time_sequence("blueprint", 0);
    log_node(&bp, layout, "root")?;
    bp.log(
        "viewport",
        &ViewportBlueprint::new().with_root_container(RootContainer(datatypes::Uuid {
            bytes: node_id("root"),
        })),
    )?;
    bp.log(
        "time_panel",
        &TimePanelBlueprint::new().with_timeline(datatypes::Utf8(TIME.into())),
    )?;
    Ok(take_messages(bp, storage))
}

/// The messages of a memory stream, and the stream let go. The SDK's memory sink holds its
/// stream (to flush it) and the stream holds its sink, so neither was ever dropped nor the
/// stream's two threads ended: every review left a pair (a campaign of 500 runs in one
/// process, 1 000 threads and their memory). A sink that holds nothing, swapped in once
/// the messages are taken, breaks the cycle: the stream ends here, with its last handles.
fn take_messages(stream: RecordingStream, storage: MemorySinkStorage) -> Vec<LogMsg> {
    let msgs = storage.take();
    stream.set_sink(Box::new(BufferedSink::new()));
    msgs
}

/// Sends `review`'s layout to `rec` as its active and default blueprint.
pub fn send_review_blueprint(rec: &RecordingStream, review: &Review) -> RecordingStreamResult<()> {
    let app_id = rec.store_info().map_or_else(
        || ApplicationId::from("unz-review"),
        |i| i.application_id().clone(),
    );
    let msgs = blueprint_messages(app_id, &review_layout(review))?;
    let Some(LogMsg::SetStoreInfo(info)) = msgs.first() else {
        return Ok(());
    };
    let blueprint_id = info.info.store_id.clone();
    rec.send_blueprint(
        msgs,
        BlueprintActivationCommand {
            blueprint_id,
            make_active: true,
            make_default: true,
        },
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_are_stable_uuids_and_distinct() {
        let a = uuid_text(&node_id("root/0"));
        assert_eq!(a, uuid_text(&node_id("root/0")));
        assert_ne!(a, uuid_text(&node_id("root/1")));
        assert_eq!(a.len(), 36);
        assert_eq!(&a[14..15], "4");
    }

    /// Regression (fuzzing every stage in one process: its threads grew by two a run): a
    /// memory stream outlived its handles, its sink and it holding each other; once its
    /// messages are taken it ends with them.
    #[test]
    fn a_memory_stream_ends_once_its_messages_are_taken() {
        let (stream, storage) = RecordingStreamBuilder::new("unz-test")
            .batcher_config(crate::rrd_sink::IN_LOGGED_ORDER)
            .memory()
            .unwrap();
        stream.set_time_sequence("blueprint", 0);
        stream.log("viewport", &ViewportBlueprint::new()).unwrap();
        let handle = stream.clone_weak();
        assert!(handle.is_enabled());
        let msgs = take_messages(stream, storage);
        // The store's info and the viewport's chunk, at least.
        assert!(msgs.len() >= 2, "{msgs:?}");
        assert!(!handle.is_enabled(), "the stream outlived its handles");
    }
}
