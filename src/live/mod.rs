//! The camera link (Note S1): the ESP32 camera's MJPEG-over-HTTP stream read on its own thread
//! (latest frame only), recording and replay, the live pipeline (decode → stitch → MMS flow →
//! tracking → JSON lines) and its browser view.
//!
//! | file | what |
//! |---|---|
//! | `url.rs` | `http://host:port/path` |
//! | `socket.rs` | a TCP read with a stall deadline that also watches the stop flag |
//! | `input.rs` | a byte buffer over any reader: lines, exact reads, reads up to a delimiter |
//! | `chunked.rs` | HTTP/1.1 chunked transfer decoding |
//! | `http.rs` | one GET: status line, headers, the body reader |
//! | `multipart.rs` | `multipart/x-mixed-replace`: boundary, part headers, part bodies |
//! | `jpeg.rs` | is it a whole JPEG: markers, then strict decoding |
//! | `reader.rs` | the reader thread: reconnection with backoff, latest-frame slot, counters |
//! | `record.rs` | `--record` and `--replay` folders |
//! | `clock.rs` | the stream's clock: processed frames' times and spans in stream frames |
//! | `tracking.rs` | the tracker of `pins track`, one flow at a time |
//! | `pipeline.rs` | frames → flow → tracks → one JSON line per processed frame |
//! | `view.rs` | the browser view's frame: tracks and predicted paths drawn, flow beside |
//! | `serve.rs` | the browser view's HTTP server (page, MJPEG re-stream, JSON, SSE) |

pub mod chunked;
pub mod clock;
pub mod http;
pub mod input;
pub mod jpeg;
pub mod multipart;
pub mod pipeline;
pub mod reader;
pub mod record;
pub mod serve;
pub mod socket;
pub mod tracking;
pub mod url;
pub mod view;
