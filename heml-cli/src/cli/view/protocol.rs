//! What the page and the server say to each other.
//!
//! Server → page: one JSON `mesh` message on connect (and again when the surface
//! changes), then binary frames of the surface positions ([`encode_frame`]), a JSON
//! `status` about ten times a second, and JSON `reply` messages answering commands.
//! Page → server: JSON commands, parsed here into [`Request`] with unknown fields and
//! unknown commands refused, every number checked finite and in range. The page can
//! name nodes, points and parameters, never a file.

use serde::{Deserialize, Serialize};

/// Largest message the server accepts from the page (bytes). A command is a few
/// hundred bytes; anything larger is refused by the WebSocket layer, which closes
/// that connection (the server and the simulation go on).
pub const MAX_MESSAGE_BYTES: usize = 4096;

/// Bytes before the positions in a binary frame (see [`encode_frame`]).
pub const FRAME_HEADER_BYTES: usize = 32;

/// Largest coordinate (m) a command may give: far beyond any organ, small enough that
/// squared lengths stay finite.
pub const MAX_COORDINATE: f64 = 1e3;

/// A scalar field the page colours the surface by.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FieldKind {
    /// |x − X| at the node (m).
    Displacement,
    /// Volume ratio J = det F, averaged over the boundary tets around the node.
    J,
    /// Strain-energy density W(F) (J/m³), averaged over the boundary tets around the node.
    Energy,
}

impl FieldKind {
    /// The id written in a frame's header.
    pub fn id(self) -> u32 {
        match self {
            FieldKind::Displacement => 0,
            FieldKind::J => 1,
            FieldKind::Energy => 2,
        }
    }
}

/// A picking ray from the camera through the cursor (world coordinates).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Ray {
    /// Start point (m).
    pub origin: [f64; 3],
    /// Direction (any length > 0).
    pub direction: [f64; 3],
}

/// A command from the page, as parsed (see [`parse_request`] for the checks).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum Request {
    /// Stop stepping.
    Pause {},
    /// Step again, at real time or as fast as the machine allows.
    Resume {},
    /// One step of dt (pauses first).
    Step {},
    /// Back to the scene's initial state.
    Reset {},
    /// Change a material parameter of the scene (e.g. `E`) and rebuild.
    SetParam {
        /// Parameter name as in the scene's `[[material]] params`.
        name: String,
        /// New value (finite, > 0).
        value: f64,
    },
    /// Choose the field the frames carry.
    Field {
        /// Which field.
        field: FieldKind,
    },
    /// Grasp the tissue at a surface node, or where a ray first meets it.
    GraspStart {
        /// A node id of the mesh message.
        #[serde(default)]
        node: Option<u32>,
        /// A picking ray, when no node is given.
        #[serde(default)]
        ray: Option<Ray>,
    },
    /// Move the grasp's target point.
    GraspMove {
        /// Target (m).
        target: [f64; 3],
    },
    /// Release the grasp.
    GraspEnd {},
    /// Move the tool tip (and optionally its axis).
    ToolMove {
        /// Tip position (m).
        position: [f64; 3],
        /// Axis direction (any length > 0); unchanged when absent.
        #[serde(default)]
        axis: Option<[f64; 3]>,
    },
    /// Cut along a blade triangle (e.g. the segment swept by a drag, from the camera).
    Cut {
        /// The blade's three corners (m).
        blade: [[f64; 3]; 3],
    },
    /// Flow control, answered by the connection itself (never forwarded, no reply):
    /// the page has received the last frame, send the newest one. A page that acks
    /// gets one frame in flight at a time, so frames never queue in the sockets while
    /// it is busy drawing (it gets the newest state, not one from a queue); a client
    /// that never acks gets every frame as fast as its socket takes them.
    Ack {},
}

/// Parses and checks one text message from the page: JSON of a known command, no
/// unknown field, every coordinate finite and within [`MAX_COORDINATE`], names short
/// and plain. The error says what was wrong (it is logged, and the message ignored).
pub fn parse_request(text: &str) -> Result<Request, String> {
    if text.len() > MAX_MESSAGE_BYTES {
        return Err(format!("message of {} bytes (limit {MAX_MESSAGE_BYTES})", text.len()));
    }
    let req: Request = serde_json::from_str(text).map_err(|e| format!("bad command: {e}"))?;
    check(&req)?;
    Ok(req)
}

fn point(what: &str, p: &[f64; 3]) -> Result<(), String> {
    if p.iter().all(|c| c.is_finite() && c.abs() <= MAX_COORDINATE) {
        Ok(())
    } else {
        Err(format!(
            "{what} {p:?}: coordinates must be finite and within ±{MAX_COORDINATE} m"
        ))
    }
}

fn direction(what: &str, d: &[f64; 3]) -> Result<(), String> {
    point(what, d)?;
    if d.iter().map(|c| c * c).sum::<f64>() > 0.0 {
        Ok(())
    } else {
        Err(format!("{what} is the zero vector"))
    }
}

fn check(req: &Request) -> Result<(), String> {
    match req {
        Request::SetParam { name, value } => {
            if name.is_empty() || name.len() > 32 || !name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
                return Err(format!("set_param: name {name:?} is not a parameter name"));
            }
            if !(value.is_finite() && *value > 0.0 && *value <= 1e12) {
                return Err(format!(
                    "set_param {name}: value {value} must be finite, > 0 and ≤ 1e12"
                ));
            }
            Ok(())
        }
        Request::GraspStart { node, ray } => match (node, ray) {
            (Some(_), None) => Ok(()),
            (None, Some(r)) => {
                point("grasp_start ray origin", &r.origin)?;
                direction("grasp_start ray direction", &r.direction)
            }
            _ => Err("grasp_start: give exactly one of `node` and `ray`".into()),
        },
        Request::GraspMove { target } => point("grasp_move target", target),
        Request::ToolMove { position, axis } => {
            point("tool_move position", position)?;
            match axis {
                Some(a) => direction("tool_move axis", a),
                None => Ok(()),
            }
        }
        Request::Cut { blade } => {
            for p in blade {
                point("cut blade corner", p)?;
            }
            Ok(())
        }
        Request::Pause {}
        | Request::Resume {}
        | Request::Step {}
        | Request::Reset {}
        | Request::Field { .. }
        | Request::GraspEnd {}
        | Request::Ack {} => Ok(()),
    }
}

/// The JSON `mesh` message: the boundary surface to draw.
#[derive(Debug, Clone, Serialize)]
pub struct MeshMessage {
    /// Always `"mesh"`.
    #[serde(rename = "type")]
    pub kind: &'static str,
    /// Bumped whenever the surface changes (a cut, a reset after one).
    pub version: u64,
    /// Mesh node id of each surface vertex (frames list positions in this order).
    pub nodes: Vec<u32>,
    /// Triangles as indices into `nodes`, outward (right-hand rule).
    pub triangles: Vec<[u32; 3]>,
    /// Rest positions of the surface vertices (m), flattened xyz.
    pub rest: Vec<f32>,
    /// Indices into `nodes` of the fixed (and prescribed) surface vertices.
    pub fixed: Vec<u32>,
    /// Bounding box of the rest mesh: [min, max] (m).
    pub bbox: [[f64; 3]; 2],
    /// What is shown: `"live"` or `"playback"`.
    pub mode: &'static str,
    /// Where it comes from (scene or output path), for the page's title.
    pub source: String,
}

impl MeshMessage {
    /// The message of a surface: `nodes` (sorted mesh node ids), `triangles` (mesh
    /// node ids, re-indexed here into `nodes`), the rest positions of all the mesh's
    /// nodes, and which nodes are held.
    pub fn new(
        nodes: Vec<u32>,
        triangles: &[[u32; 3]],
        rest: &[heml::Vec3],
        is_fixed: impl Fn(u32) -> bool,
        version: u64,
        mode: &'static str,
        source: &str,
    ) -> Self {
        let local = |n: u32| nodes.binary_search(&n).unwrap_or(0) as u32;
        let triangles = triangles.iter().map(|t| t.map(local)).collect();
        let rest_xyz = nodes
            .iter()
            .flat_map(|&n| {
                let p = rest[n as usize];
                [p.x as f32, p.y as f32, p.z as f32]
            })
            .collect();
        let fixed = nodes
            .iter()
            .enumerate()
            .filter(|(_, &n)| is_fixed(n))
            .map(|(k, _)| k as u32)
            .collect();
        let (lo, hi) = super::control::bounds(rest);
        MeshMessage {
            kind: "mesh",
            version,
            nodes,
            triangles,
            rest: rest_xyz,
            fixed,
            bbox: [[lo.x, lo.y, lo.z], [hi.x, hi.y, hi.z]],
            mode,
            source: source.into(),
        }
    }
}

/// The JSON `status` message, about ten times a second.
#[derive(Debug, Clone, Serialize, Default)]
pub struct Status {
    /// Always `"status"`.
    #[serde(rename = "type")]
    pub kind: &'static str,
    /// Simulated time (s).
    pub time: f64,
    /// Steps taken since the start (or the last reset).
    pub steps: u64,
    /// Frames published since the start.
    pub frame: u64,
    /// Stepping is paused.
    pub paused: bool,
    /// Simulated seconds per wall-clock second over the last status period.
    pub real_time_factor: f64,
    /// Median wall time of a step over the last status period (ms; 1 / `STATUS_HZ` = 0.1 s).
    pub step_ms_p50: f64,
    /// 99th percentile of the step wall time over the last status period (ms).
    pub step_ms_p99: f64,
    /// Integrator name.
    pub integrator: String,
    /// Time step (s): the one the last step took (an explicit integrator steps
    /// adaptively, so the next step may differ).
    pub dt: f64,
    /// Smallest volume ratio J over the tets.
    pub min_j: f64,
    /// Force the tissue applies to the hand (N): to the grasp while one is held, else
    /// to the tool, when a tool exists.
    pub tool_force: Option<[f64; 3]>,
    /// The grasp in progress, if any.
    pub grasp: Option<GraspView>,
    /// Where the tool is, to draw it, when a tool exists.
    pub tool: Option<ToolView>,
    /// The law of the first material and its parameters as the law holds them.
    pub law: String,
    /// The first material's law parameters (name, value), e.g. mu and lambda.
    pub law_params: Vec<(String, f64)>,
    /// The scene's parameters of the first material (e.g. E and nu), as last set.
    pub scene_params: Vec<(String, f64)>,
    /// The field the frames carry.
    pub field: Option<FieldKind>,
    /// Last error of the simulation (a blow-up), if it stopped on one.
    pub error: Option<String>,
}

/// A grasp in progress, as the status reports it.
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct GraspView {
    /// Number of grasped nodes.
    pub nodes: usize,
    /// Mean distance of the grasped nodes from where they were when grasped (m).
    pub moved: f64,
}

/// A capsule tool as the page draws it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ToolView {
    /// Tip (m).
    pub tip: [f64; 3],
    /// Unit axis, from the tip towards the handle.
    pub axis: [f64; 3],
    /// Radius (m).
    pub radius: f64,
    /// Shaft length (m).
    pub length: f64,
}

/// The JSON `reply` to a command the simulation refused or could not carry out.
#[derive(Debug, Clone, Serialize)]
pub struct Reply {
    /// Always `"reply"`.
    #[serde(rename = "type")]
    pub kind: &'static str,
    /// The command's `type`.
    pub command: String,
    /// Carried out.
    pub ok: bool,
    /// What happened, for the page to show.
    pub message: String,
}

impl Reply {
    /// A reply as JSON text.
    pub fn json(command: &str, ok: bool, message: impl Into<String>) -> String {
        let r = Reply {
            kind: "reply",
            command: command.into(),
            ok,
            message: message.into(),
        };
        serde_json::to_string(&r).unwrap_or_default()
    }
}

/// The name of a command, for replies and logs.
pub fn request_name(req: &Request) -> &'static str {
    match req {
        Request::Pause {} => "pause",
        Request::Resume {} => "resume",
        Request::Step {} => "step",
        Request::Reset {} => "reset",
        Request::SetParam { .. } => "set_param",
        Request::Field { .. } => "field",
        Request::GraspStart { .. } => "grasp_start",
        Request::GraspMove { .. } => "grasp_move",
        Request::GraspEnd {} => "grasp_end",
        Request::ToolMove { .. } => "tool_move",
        Request::Cut { .. } => "cut",
        Request::Ack {} => "ack",
    }
}

/// A binary frame: header then data, all little-endian.
///
/// | offset | type | content |
/// |---|---|---|
/// | 0 | u32 | frame number |
/// | 4 | u32 | n, surface vertices |
/// | 8 | f64 | simulated time (s) |
/// | 16 | f32 | field minimum |
/// | 20 | f32 | field maximum |
/// | 24 | u32 | field id ([`FieldKind::id`]) |
/// | 28 | u32 | mesh version ([`MeshMessage::version`]) |
/// | 32 | 3n × f32 | positions (m), xyz per vertex |
/// | 32 + 12n | n × f32 | field value per vertex |
pub fn encode_frame(
    frame: u64,
    time: f64,
    field: FieldKind,
    mesh_version: u64,
    xyz: &[f32],
    values: &[f32],
) -> Vec<u8> {
    let n = values.len();
    debug_assert_eq!(xyz.len(), 3 * n);
    let (lo, hi) = values
        .iter()
        .filter(|v| v.is_finite())
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &v| (a.min(v), b.max(v)));
    let (lo, hi) = if lo <= hi { (lo, hi) } else { (0.0, 0.0) };
    let mut out = Vec::with_capacity(FRAME_HEADER_BYTES + 16 * n);
    out.extend_from_slice(&(frame as u32).to_le_bytes());
    out.extend_from_slice(&(n as u32).to_le_bytes());
    out.extend_from_slice(&time.to_le_bytes());
    out.extend_from_slice(&lo.to_le_bytes());
    out.extend_from_slice(&hi.to_le_bytes());
    out.extend_from_slice(&field.id().to_le_bytes());
    out.extend_from_slice(&(mesh_version as u32).to_le_bytes());
    for v in xyz.iter().chain(values) {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn commands_parse_into_the_typed_enum() {
        assert_eq!(parse_request(r#"{"type":"pause"}"#), Ok(Request::Pause {}));
        assert_eq!(
            parse_request(r#"{"type":"set_param","name":"E","value":2e4}"#),
            Ok(Request::SetParam {
                name: "E".into(),
                value: 2e4
            })
        );
        assert_eq!(
            parse_request(r#"{"type":"field","field":"j"}"#),
            Ok(Request::Field { field: FieldKind::J })
        );
    }

    #[test]
    fn bad_commands_are_refused_with_a_reason() {
        for (text, why) in [
            ("not json", "bad command"),
            (r#"{"type":"explode"}"#, "unknown variant"),
            (r#"{"type":"pause","extra":1}"#, "unknown field"),
            (r#"{"type":"set_param","name":"E","value":-1}"#, "must be finite"),
            (r#"{"type":"set_param","name":"E","value":1e999}"#, "bad command"),
            (
                r#"{"type":"set_param","name":"../etc/passwd","value":1}"#,
                "not a parameter name",
            ),
            (r#"{"type":"grasp_move","target":[0,1e9,0]}"#, "within"),
            (r#"{"type":"grasp_start"}"#, "exactly one"),
            (
                r#"{"type":"grasp_start","ray":{"origin":[0,0,0],"direction":[0,0,0]}}"#,
                "zero vector",
            ),
            (r#"{"type":"field","field":"file:///etc"}"#, "unknown variant"),
        ] {
            let err = parse_request(text).unwrap_err();
            assert!(err.contains(why), "{text}: {err}");
        }
        let big = format!(
            r#"{{"type":"set_param","name":"E","value":1{}}}"#,
            "0".repeat(MAX_MESSAGE_BYTES)
        );
        assert!(parse_request(&big).unwrap_err().contains("limit"));
    }

    #[test]
    fn a_frame_has_the_documented_layout() {
        let xyz = [1.0f32, 2.0, 3.0, 4.0, 5.0, 6.0];
        let values = [0.5f32, -0.25];
        let b = encode_frame(7, 0.125, FieldKind::J, 3, &xyz, &values);
        assert_eq!(b.len(), FRAME_HEADER_BYTES + 16 * 2);
        let u32_at = |o: usize| u32::from_le_bytes(b[o..o + 4].try_into().unwrap());
        let f32_at = |o: usize| f32::from_le_bytes(b[o..o + 4].try_into().unwrap());
        assert_eq!((u32_at(0), u32_at(4), u32_at(24), u32_at(28)), (7, 2, 1, 3));
        assert_eq!(f64::from_le_bytes(b[8..16].try_into().unwrap()), 0.125);
        assert_eq!((f32_at(16), f32_at(20)), (-0.25, 0.5));
        assert_eq!(f32_at(32 + 4 * 5), 6.0);
        assert_eq!(f32_at(32 + 12 * 2 + 4), -0.25);
    }
}
