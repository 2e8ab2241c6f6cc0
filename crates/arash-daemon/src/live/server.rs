//! The live stream's WebSocket server (Foxglove WebSocket protocol, subprotocol
//! `foxglove.sdk.v1` or the older `foxglove.websocket.v1`).
//!
//! The protocol's messages (server info, channel advertisements, subscriptions, message data)
//! are the Foxglove SDK's own types and encoders. The SDK's server is not used: it drops a slow
//! client's messages without telling anyone, and the operator must see how many a client lost.
//! So each client has a bounded queue here: the logger thread pushes into it without waiting,
//! and a full queue drops the message and counts it.
//!
//! Read-only: the server advertises no capability, so a client can subscribe and nothing else;
//! any other request is ignored.

use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

use arash_core::flightlog::schema::{descriptor_set, CYCLE_SCHEMA, ERROR_SCHEMA};
use arash_core::flightlog::{CYCLE_TOPIC, ERROR_TOPIC, EVENT_TOPIC, ROBOT_DESCRIPTION_TOPIC, TIMING_TOPIC};
use foxglove::messages::{FrameTransforms, SceneUpdate};
use foxglove::ws_protocol::client::ClientMessage;
use foxglove::ws_protocol::schema::Schema;
use foxglove::ws_protocol::server::{Advertise, Channel, MessageData, ServerInfo};
use foxglove::ws_protocol::{BinaryMessage, JsonMessage};
use foxglove::Encode;
use futures_util::{SinkExt, StreamExt};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::mpsc;
use tokio_tungstenite::tungstenite::handshake::server::{ErrorResponse, Request, Response};
use tokio_tungstenite::tungstenite::http::HeaderValue;
use tokio_tungstenite::tungstenite::Message;

use super::scene::{timestamp, Scene};

/// The subprotocols a client may ask for, preferred first. Both carry the schemas inline in
/// each advertisement, which is all this server sends.
const SUBPROTOCOLS: [&str; 2] = ["foxglove.sdk.v1", "foxglove.websocket.v1"];

/// The stream's channels; the discriminant is the advertised channel id.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Topic {
    /// `/arash/cycle`, one cycle per display window (`arash.Cycle`, as in the flight log).
    Cycle = 1,
    /// `/arash/error`, the window's tracking error and its extremes (`arash.TrackingError`).
    Error = 2,
    /// `/arash/timing`, once a second (JSON, as in the flight log).
    Timing = 3,
    /// `/arash/event` (JSON, as in the flight log).
    Event = 4,
    /// `/robot_description`, the URDF, sent to each client when it subscribes.
    RobotDescription = 5,
    /// `/arash/transforms`, each moving link in its parent at the window's cycle
    /// (`foxglove.FrameTransforms`): the URDF moves in the 3D panel.
    Transforms = 6,
    /// `/arash/hand_force_arrow`, the hand's force as an arrow at its frame
    /// (`foxglove.SceneUpdate`).
    HandArrow = 7,
    /// `/arash/fixture_force_arrow`, the fixtures' rendered force as an arrow at the instrument
    /// tip (`foxglove.SceneUpdate`; no arrow outside the haptic mode).
    FixtureArrow = 8,
}

const TOPICS: [Topic; 8] = [
    Topic::Cycle,
    Topic::Error,
    Topic::Timing,
    Topic::Event,
    Topic::RobotDescription,
    Topic::Transforms,
    Topic::HandArrow,
    Topic::FixtureArrow,
];

/// The live stream's own topics, beside the flight log's.
pub const TRANSFORMS_TOPIC: &str = "/arash/transforms";
pub const HAND_ARROW_TOPIC: &str = "/arash/hand_force_arrow";
pub const FIXTURE_ARROW_TOPIC: &str = "/arash/fixture_force_arrow";

impl Topic {
    fn from_id(id: u64) -> Option<Topic> {
        TOPICS.into_iter().find(|t| *t as u64 == id)
    }

    fn name(self) -> &'static str {
        match self {
            Topic::Cycle => CYCLE_TOPIC,
            Topic::Error => ERROR_TOPIC,
            Topic::Timing => TIMING_TOPIC,
            Topic::Event => EVENT_TOPIC,
            Topic::RobotDescription => ROBOT_DESCRIPTION_TOPIC,
            Topic::Transforms => TRANSFORMS_TOPIC,
            Topic::HandArrow => HAND_ARROW_TOPIC,
            Topic::FixtureArrow => FIXTURE_ARROW_TOPIC,
        }
    }
}

/// Counters shown by `arash ctl status`.
#[derive(Debug, Default)]
struct Counters {
    clients: AtomicU64,
    connections: AtomicU64,
    sent: AtomicU64,
    dropped: AtomicU64,
}

/// One connected client: its queue, its subscriptions (channel id → subscription id) and what
/// it lost.
struct Client {
    queue: mpsc::Sender<Message>,
    subscriptions: Mutex<HashMap<u64, u32>>,
    dropped: AtomicU64,
    peer: String,
}

pub struct LiveServer {
    address: std::net::SocketAddr,
    clients: Mutex<Vec<Arc<Client>>>,
    counters: Counters,
    queue: usize,
    advertise: String,
    info: String,
    robot_description: Vec<u8>,
    /// The 3D panel's kinematics (the logger thread alone draws with it).
    scene: Mutex<Scene>,
}

impl LiveServer {
    /// A server for a robot with `urdf` whose error display units are `units` (one per joint),
    /// queueing up to `queue` messages per client; the hand's force is drawn at `frame`.
    pub fn new(
        address: std::net::SocketAddr,
        urdf: &str,
        units: &[&str],
        queue: usize,
        frame: Option<&str>,
    ) -> anyhow::Result<Self> {
        let scene = Scene::new(arash_core::parse_urdf(urdf)?, frame)?;
        let info = ServerInfo::new("arash-daemon")
            .with_metadata([("arash_version".to_string(), env!("CARGO_PKG_VERSION").to_string())].into())
            .to_string();
        Ok(Self {
            address,
            clients: Mutex::default(),
            counters: Counters::default(),
            queue,
            advertise: advertisement(units)?,
            info,
            robot_description: serde_json::json!({ "data": urdf }).to_string().into_bytes(),
            scene: Mutex::new(scene),
        })
    }

    /// Hand `payload` (encoded as the topic's schema says) to every client subscribed to
    /// `topic`. Never waits: a full queue drops the message for that client and counts it.
    pub fn publish(&self, topic: Topic, log_time: u64, payload: &[u8]) {
        let clients = self.clients.lock().expect("client list lock");
        for client in clients.iter() {
            let Some(&subscription) = client.subscriptions.lock().expect("subscriptions lock").get(&(topic as u64))
            else {
                continue;
            };
            self.offer(client, Message::Binary(MessageData::new(subscription, log_time, payload).to_bytes().into()));
        }
    }

    /// The 3D panel at a window's cycle: the links at `q`, the hand's force `frame_force` (N,
    /// base frame; empty without a frame) and the fixtures' `fixture_force` (N, base frame) as
    /// arrows, each drawn only while someone watches.
    pub fn publish_scene(&self, log_time: u64, q: &[f64], (frame_force, fixture_force): (&[f64], &[f64])) {
        let watched = |topic: Topic| {
            self.clients
                .lock()
                .expect("client list lock")
                .iter()
                .any(|c| c.subscriptions.lock().expect("subscriptions lock").contains_key(&(topic as u64)))
        };
        let (links, arrow, fixtures) =
            (watched(Topic::Transforms), watched(Topic::HandArrow), watched(Topic::FixtureArrow));
        if !(links || arrow || fixtures) {
            return;
        }
        let time = timestamp(log_time);
        let mut scene = self.scene.lock().expect("scene lock");
        scene.place(q);
        let mut payload = Vec::new();
        if links {
            scene.transforms(time).encode(&mut payload).expect("a Vec grows as needed");
            self.publish(Topic::Transforms, log_time, &payload);
        }
        if arrow {
            payload.clear();
            scene.hand_arrow(frame_force, time).encode(&mut payload).expect("a Vec grows as needed");
            self.publish(Topic::HandArrow, log_time, &payload);
        }
        if fixtures {
            payload.clear();
            scene.fixture_arrow(fixture_force, time).encode(&mut payload).expect("a Vec grows as needed");
            self.publish(Topic::FixtureArrow, log_time, &payload);
        }
    }

    fn offer(&self, client: &Client, message: Message) {
        match client.queue.try_send(message) {
            Ok(()) => {
                self.counters.sent.fetch_add(1, Ordering::Relaxed);
            }
            Err(mpsc::error::TrySendError::Full(_)) => {
                client.dropped.fetch_add(1, Ordering::Relaxed);
                self.counters.dropped.fetch_add(1, Ordering::Relaxed);
            }
            // The client is leaving; its task removes it from the list.
            Err(mpsc::error::TrySendError::Closed(_)) => {}
        }
    }

    /// What `arash ctl status` shows under `live`.
    pub fn status(&self) -> serde_json::Value {
        let c = &self.counters;
        let clients: Vec<_> = self
            .clients
            .lock()
            .expect("client list lock")
            .iter()
            .map(|client| {
                serde_json::json!({
                    "peer": client.peer,
                    "subscriptions": client.subscriptions.lock().expect("subscriptions lock").len(),
                    "dropped": client.dropped.load(Ordering::Relaxed),
                })
            })
            .collect();
        serde_json::json!({
            "address": self.address.to_string(),
            "clients": c.clients.load(Ordering::Relaxed),
            "connections": c.connections.load(Ordering::Relaxed),
            "sent": c.sent.load(Ordering::Relaxed),
            "dropped": c.dropped.load(Ordering::Relaxed),
            "per_client": clients,
        })
    }

    /// Accept clients until the future is dropped (at the daemon's stop).
    pub async fn serve(self: Arc<Self>, listener: TcpListener) {
        loop {
            match listener.accept().await {
                Ok((stream, peer)) => {
                    tokio::spawn(self.clone().client(stream, peer.to_string()));
                }
                Err(e) => {
                    eprintln!("arash-daemon: live stream: accept failed: {e}");
                    tokio::time::sleep(std::time::Duration::from_millis(100)).await;
                }
            }
        }
    }

    async fn client(self: Arc<Self>, stream: TcpStream, peer: String) {
        let _ = stream.set_nodelay(true);
        let ws = match tokio_tungstenite::accept_hdr_async(stream, choose_subprotocol).await {
            Ok(ws) => ws,
            Err(e) => {
                eprintln!("arash-daemon: live stream: refused {peer}: {e}");
                return;
            }
        };
        let (mut sink, mut source) = ws.split();
        if sink.send(Message::Text(self.info.clone().into())).await.is_err()
            || sink.send(Message::Text(self.advertise.clone().into())).await.is_err()
        {
            return;
        }
        let (tx, mut rx) = mpsc::channel(self.queue);
        let client = Arc::new(Client {
            queue: tx,
            subscriptions: Mutex::default(),
            dropped: AtomicU64::new(0),
            peer: peer.clone(),
        });
        self.clients.lock().expect("client list lock").push(client.clone());
        self.counters.clients.fetch_add(1, Ordering::Relaxed);
        self.counters.connections.fetch_add(1, Ordering::Relaxed);
        eprintln!("arash-daemon: live stream: {peer} connected");
        loop {
            tokio::select! {
                incoming = source.next() => match incoming {
                    Some(Ok(message)) => self.request(&client, &message),
                    Some(Err(_)) | None => break,
                },
                outgoing = rx.recv() => match outgoing {
                    Some(message) => if sink.send(message).await.is_err() { break },
                    None => break,
                },
            }
        }
        self.clients.lock().expect("client list lock").retain(|c| !Arc::ptr_eq(c, &client));
        self.counters.clients.fetch_sub(1, Ordering::Relaxed);
        eprintln!(
            "arash-daemon: live stream: {peer} disconnected ({} messages dropped)",
            client.dropped.load(Ordering::Relaxed)
        );
    }

    /// A client's request: subscriptions are honoured, everything else is ignored (the
    /// stream is read-only and advertises no capability that would allow more).
    fn request(&self, client: &Client, message: &Message) {
        let Ok(request) = ClientMessage::try_from(message) else { return };
        match request {
            ClientMessage::Subscribe(s) => {
                for sub in s.subscriptions {
                    let Some(topic) = Topic::from_id(sub.channel_id) else { continue };
                    client.subscriptions.lock().expect("subscriptions lock").insert(sub.channel_id, sub.id);
                    if topic == Topic::RobotDescription {
                        let data = MessageData::new(sub.id, now_ns(), &self.robot_description[..]);
                        self.offer(client, Message::Binary(data.to_bytes().into()));
                    }
                }
            }
            ClientMessage::Unsubscribe(u) => {
                client
                    .subscriptions
                    .lock()
                    .expect("subscriptions lock")
                    .retain(|_, id| !u.subscription_ids.contains(id));
            }
            _ => {}
        }
    }
}

fn now_ns() -> u64 {
    std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_nanos() as u64)
}

/// The WebSocket handshake: answer with the first of [`SUBPROTOCOLS`] the client offers, or
/// refuse it with 400.
#[allow(clippy::result_large_err)] // tungstenite's callback type
fn choose_subprotocol(request: &Request, mut response: Response) -> Result<Response, ErrorResponse> {
    let offered: Vec<&str> = request
        .headers()
        .get_all("sec-websocket-protocol")
        .iter()
        .flat_map(|h| h.to_str().unwrap_or_default().split(','))
        .map(str::trim)
        .collect();
    match SUBPROTOCOLS.into_iter().find(|p| offered.contains(p)) {
        Some(chosen) => {
            response.headers_mut().insert("sec-websocket-protocol", HeaderValue::from_static(chosen));
            Ok(response)
        }
        None => {
            let mut refusal = ErrorResponse::new(Some(format!("ask for subprotocol {}", SUBPROTOCOLS.join(" or "))));
            *refusal.status_mut() = tokio_tungstenite::tungstenite::http::StatusCode::BAD_REQUEST;
            Err(refusal)
        }
    }
}

/// The `advertise` message: every channel, with the flight log's schemas inline.
fn advertisement(units: &[&str]) -> anyhow::Result<String> {
    let protobuf = |topic: Topic, schema: &'static str| {
        Channel::builder(topic as u64, topic.name(), "protobuf").with_schema(Schema::new(
            schema,
            "protobuf",
            descriptor_set(schema),
        ))
    };
    let json = |topic: Topic, name: &'static str, schema: &'static str| {
        Channel::builder(topic as u64, topic.name(), "json").with_schema(Schema::new(
            name,
            "jsonschema",
            schema.as_bytes().to_vec(),
        ))
    };
    let object = r#"{"type":"object"}"#;
    // Foxglove's own schemas, which its 3D panel draws.
    let foxglove_schema = |topic: Topic, schema: Option<foxglove::Schema>| {
        let schema = schema.expect("Foxglove's messages carry their schema");
        Channel::builder(topic as u64, topic.name(), "protobuf").with_schema(Schema::new(
            schema.name,
            schema.encoding,
            schema.data.into_owned(),
        ))
    };
    let channels = [
        protobuf(Topic::Cycle, CYCLE_SCHEMA),
        protobuf(Topic::Error, ERROR_SCHEMA).with_metadata([("units".to_string(), units.join(","))].into()),
        json(Topic::Timing, "arash.Timing", object),
        json(Topic::Event, "arash.Event", object),
        // The name Foxglove's URDF layer looks for on a topic.
        json(
            Topic::RobotDescription,
            "std_msgs/String",
            r#"{"type":"object","properties":{"data":{"type":"string"}}}"#,
        ),
        foxglove_schema(Topic::Transforms, FrameTransforms::get_schema()),
        foxglove_schema(Topic::HandArrow, SceneUpdate::get_schema()),
        foxglove_schema(Topic::FixtureArrow, SceneUpdate::get_schema()),
    ]
    .into_iter()
    .map(|builder| builder.build())
    .collect::<Result<Vec<_>, _>>()?;
    Ok(Advertise::new(channels).to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_advertisement_carries_every_topic_with_a_decodable_schema() {
        let text = advertisement(&["deg", "deg", "um"]).unwrap();
        let parsed = foxglove::ws_protocol::server::ServerMessage::parse_json(&text).unwrap();
        let foxglove::ws_protocol::server::ServerMessage::Advertise(a) = parsed else { panic!("{text}") };
        let topics: Vec<_> = a.channels.iter().map(|c| (c.id, c.topic.to_string())).collect();
        assert_eq!(topics, TOPICS.iter().map(|t| (*t as u64, t.name().to_string())).collect::<Vec<_>>());
        assert_eq!(a.channels[0].decode_schema().unwrap(), descriptor_set(CYCLE_SCHEMA));
        assert_eq!(a.channels[1].metadata["units"], "deg,deg,um");
    }
}
