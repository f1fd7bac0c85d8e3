//! The module's exports for clients that synthesize tiles themselves ([`crate::client`] as a
//! raw ABI of numbers and two buffers, so no bindings generator is needed;
//! `client-web/src/shared/vtex-synth.js` wraps it for JavaScript).
//!
//! - The caller writes bundle bytes into the *input* buffer ([`vtex_input`]), then calls
//!   [`vtex_open`] with the tile size to cut it into, which answers a handle (never 0) and the
//!   texture's info (the server's `TextureInfo` for that tile size), or 0.
//! - Every call that produces something writes it into the *output* buffer ([`vtex_output`],
//!   [`vtex_output_len`]) and answers non-zero; on failure it writes the error message (UTF-8)
//!   there and answers 0. Both buffers belong to the module and are reused by the next call.
//! - A panic (a bug: bad input is an error, never a panic) traps; its message is kept for
//!   [`vtex_panic_message`], and the caller must then drop the instance (a trapped call may
//!   leave the module's state locked).

use crate::client::{self, Opened};
use std::collections::BTreeMap;
use std::sync::{LazyLock, Mutex, MutexGuard};
use vtex_synth::Region;
use vtex_wire::TextureInfo;

#[derive(Default)]
struct State {
    input: Vec<u8>,
    output: Vec<u8>,
    textures: BTreeMap<u32, Opened>,
    /// Handles are never reused, so a closed handle is an error, not another texture.
    last_handle: u32,
}

static STATE: LazyLock<Mutex<State>> = LazyLock::new(Default::default);
static PANIC: Mutex<String> = Mutex::new(String::new());

fn state() -> MutexGuard<'static, State> {
    // Only a panic poisons the lock, and the instance is dead after one anyway.
    STATE.lock().unwrap_or_else(|e| e.into_inner())
}

/// Stores `result` in the output buffer and answers `ok` (non-zero), or stores the error's
/// message and answers 0.
fn answer(st: &mut State, result: Result<Vec<u8>, String>, ok: u32) -> u32 {
    match result {
        Ok(bytes) => {
            st.output = bytes;
            ok
        }
        Err(message) => {
            st.output = message.into_bytes();
            0
        }
    }
}

fn opened(st: &State, handle: u32) -> Result<&Opened, String> {
    st.textures.get(&handle).ok_or_else(|| format!("no open texture has handle {handle}"))
}

fn info_json(info: &TextureInfo) -> Vec<u8> {
    serde_json::to_vec(info).expect("an info always serializes")
}

/// A coordinate from JavaScript (a double) as an integer, or why it is not one.
fn coordinate(name: &str, v: f64) -> Result<i64, String> {
    const SAFE: f64 = 9_007_199_254_740_991.0; // 2^53 - 1: every integer up to it is exact
    if v.fract() == 0.0 && v.abs() <= SAFE {
        Ok(v as i64)
    } else {
        Err(format!("invalid region: {name} = {v} is not an integer within ±(2^53 - 1)"))
    }
}

/// Installs the hook that keeps a panic's message for [`vtex_panic_message`]. The wrapper
/// calls it once per instance, first.
#[allow(unsafe_code)] // an unmangled export, as every function below
#[no_mangle]
pub extern "C" fn vtex_init() {
    std::panic::set_hook(Box::new(|info| {
        if let Ok(mut message) = PANIC.try_lock() {
            *message = info.to_string();
        }
    }));
}

/// Resizes the input buffer to `len` bytes (zeroed) and answers where to write them.
#[allow(unsafe_code)]
#[no_mangle]
pub extern "C" fn vtex_input(len: u32) -> *mut u8 {
    let mut st = state();
    st.input.clear();
    st.input.resize(len as usize, 0);
    st.input.as_mut_ptr()
}

/// The output buffer of the last call.
#[allow(unsafe_code)]
#[no_mangle]
pub extern "C" fn vtex_output() -> *const u8 {
    state().output.as_ptr()
}

/// Bytes in the output buffer.
#[allow(unsafe_code)]
#[no_mangle]
pub extern "C" fn vtex_output_len() -> u32 {
    state().output.len() as u32
}

/// Opens the bundle in the input buffer (and frees it), cut into tiles of `tile_size` (at most
/// [`client::MAX_TILE_SIZE`]): a handle and the texture's info as JSON, or 0 and the error.
#[allow(unsafe_code)]
#[no_mangle]
pub extern "C" fn vtex_open(tile_size: u32) -> u32 {
    let mut st = state();
    let bytes = std::mem::take(&mut st.input);
    match client::open(&bytes, tile_size) {
        Ok(opened) => {
            st.last_handle += 1;
            let handle = st.last_handle;
            st.output = info_json(&opened.info);
            st.textures.insert(handle, opened);
            handle
        }
        Err(message) => answer(&mut st, Err(message), 0),
    }
}

/// The info of an open texture as JSON, or 0 and the error.
#[allow(unsafe_code)]
#[no_mangle]
pub extern "C" fn vtex_info(handle: u32) -> u32 {
    let mut st = state();
    let result = opened(&st, handle).map(|t| info_json(&t.info));
    answer(&mut st, result, 1)
}

/// Renders a region of `level` at `frame` into the output buffer as RGBA8, or 0 and the
/// error. `x` and `y` are integers carried as doubles (JavaScript numbers).
#[allow(unsafe_code)]
#[no_mangle]
pub extern "C" fn vtex_render(handle: u32, level: u32, x: f64, y: f64, width: u32, height: u32, frame: u32) -> u32 {
    let mut st = state();
    let result = opened(&st, handle).and_then(|t| {
        let region = Region::new(level, coordinate("x", x)?, coordinate("y", y)?, width, height).at_frame(frame);
        t.render(&region)
    });
    answer(&mut st, result, 1)
}

/// Renders tile (`tx`, `ty`) of `level` at `frame`, cut as the server cuts tiles of the size
/// the texture was opened with, into the output buffer as RGBA8; answers the tile's width and
/// height packed as `width << 16 | height`, or 0 and the error.
#[allow(unsafe_code)]
#[no_mangle]
pub extern "C" fn vtex_render_tile(handle: u32, level: u32, tx: u32, ty: u32, frame: u32) -> u32 {
    let mut st = state();
    let mut size = 0;
    let result = opened(&st, handle).and_then(|t| {
        let region = t.tile_region(level, tx, ty, frame)?;
        size = region.width << 16 | region.height;
        t.render(&region)
    });
    answer(&mut st, result, size)
}

/// Closes a texture: 1, or 0 and the error when the handle is not open.
#[allow(unsafe_code)]
#[no_mangle]
pub extern "C" fn vtex_close(handle: u32) -> u32 {
    let mut st = state();
    let result =
        st.textures.remove(&handle).map(|_| Vec::new()).ok_or_else(|| format!("no open texture has handle {handle}"));
    answer(&mut st, result, 1)
}

/// The message of the panic that trapped the instance (UTF-8, [`vtex_panic_message_len`]
/// bytes; empty when there was none). Reads nothing the trapped call may have left locked.
#[allow(unsafe_code)]
#[no_mangle]
pub extern "C" fn vtex_panic_message() -> *const u8 {
    PANIC.lock().map(|m| m.as_ptr()).unwrap_or(std::ptr::null())
}

/// Bytes of [`vtex_panic_message`].
#[allow(unsafe_code)]
#[no_mangle]
pub extern "C" fn vtex_panic_message_len() -> u32 {
    PANIC.lock().map(|m| m.len() as u32).unwrap_or(0)
}
