//! The ports of one worker's channels, seen from the supervisor ([`SupervisorPorts`],
//! [`BlockListener`]) and from the worker ([`WorkerPorts`], [`CmdWaker`]).

use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;
use iceoryx2::sample::Sample;

use crate::error::IpcError;
use crate::error::ice;
use crate::services::{
    BlockHeader, ChannelSettings, CmdHeader, block_event_service, block_service, cmd_event_service,
    cmd_service,
};
use crate::{BlockSample, BlockSampleMut, Svc};

/// Supervisor-side ports of one worker. `Send`.
pub struct SupervisorPorts {
    cmd_pub: Publisher<Svc, [u64], CmdHeader>,
    cmd_notifier: Notifier<Svc>,
    block_sub: Subscriber<Svc, [u64], BlockHeader>,
    /// Commands sent so far (all processes of the worker).
    sent: std::sync::atomic::AtomicU64,
}

impl std::fmt::Debug for SupervisorPorts {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("SupervisorPorts")
    }
}

impl SupervisorPorts {
    /// Open the ports of worker `worker`; `max_cmd_words` is the largest command payload.
    pub fn new(node: &Node<Svc>, worker: usize, max_cmd_words: usize) -> Result<Self, IpcError> {
        let block_sub = block_service(node, worker)?
            .subscriber_builder()
            .create()
            .map_err(ice(format!("create block subscriber of worker {worker}")))?;
        let cmd_pub = cmd_service(node, worker)?
            .publisher_builder()
            .initial_max_slice_len(max_cmd_words.max(1))
            .max_loaned_samples(1)
            .create()
            .map_err(ice(format!("create command publisher of worker {worker}")))?;
        let cmd_notifier = cmd_event_service(node, worker)?
            .notifier_builder()
            .create()
            .map_err(ice(format!("create command notifier of worker {worker}")))?;
        Ok(SupervisorPorts {
            cmd_pub,
            cmd_notifier,
            block_sub,
            sent: Default::default(),
        })
    }

    /// Send a command: `fill` writes the payload words (all `len` of them), then the worker is
    /// woken up.
    pub fn send_cmd(
        &self,
        seq: u64,
        kind: u32,
        len: usize,
        fill: impl FnOnce(&mut [u64]),
    ) -> Result<(), IpcError> {
        let s = self
            .cmd_pub
            .loan_slice(len.max(1))
            .map_err(ice("loan command sample"))?;
        let mut s = s;
        *s.user_header_mut() = CmdHeader {
            seq,
            kind,
            len: len as u32,
        };
        fill(&mut s.payload_mut()[..len]);
        s.send().map_err(ice("send command"))?;
        self.sent.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        self.cmd_notifier.notify().map_err(ice("notify worker"))?;
        Ok(())
    }

    /// Commands sent so far through these ports (to every process of the worker).
    pub fn sent(&self) -> u64 {
        self.sent.load(std::sync::atomic::Ordering::Relaxed)
    }

    /// Take the next received block, if any.
    pub fn try_recv(&self) -> Result<Option<BlockSample>, IpcError> {
        self.block_sub.receive().map_err(ice("receive block"))
    }
}

/// The supervisor's listener for "a block is ready" events.
pub struct BlockListener {
    listener: Listener<Svc>,
}

impl std::fmt::Debug for BlockListener {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("BlockListener")
    }
}

impl BlockListener {
    /// Create the listener (supervisor side).
    pub fn new(node: &Node<Svc>, s: &ChannelSettings) -> Result<Self, IpcError> {
        let listener = block_event_service(node, s)?
            .listener_builder()
            .create()
            .map_err(ice("create block listener"))?;
        Ok(BlockListener { listener })
    }
    /// The underlying listener (for [`crate::hybrid_wait`]).
    pub fn listener(&self) -> &Listener<Svc> {
        &self.listener
    }
}

/// Worker-side ports.
pub struct WorkerPorts {
    cmd_sub: Subscriber<Svc, [u64], CmdHeader>,
    cmd_listener: Listener<Svc>,
    block_pub: Publisher<Svc, [u64], BlockHeader>,
    block_notifier: Notifier<Svc>,
}

impl std::fmt::Debug for WorkerPorts {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("WorkerPorts")
    }
}

impl WorkerPorts {
    /// Open the ports of worker `worker`; `block_words` is the payload size of every block.
    pub fn new(
        node: &Node<Svc>,
        worker: usize,
        block_words: usize,
        s: &ChannelSettings,
    ) -> Result<Self, IpcError> {
        let cmd_sub = cmd_service(node, worker)?
            .subscriber_builder()
            .create()
            .map_err(ice(format!("create command subscriber of worker {worker}")))?;
        let cmd_listener = cmd_event_service(node, worker)?
            .listener_builder()
            .create()
            .map_err(ice(format!("create command listener of worker {worker}")))?;
        let block_pub = block_service(node, worker)?
            .publisher_builder()
            .initial_max_slice_len(block_words.max(1))
            .max_loaned_samples(1)
            .create()
            .map_err(ice(format!("create block publisher of worker {worker}")))?;
        let event_id = EventId::new(worker);
        let block_notifier = block_event_service(node, s)?
            .notifier_builder()
            .default_event_id(event_id)
            .create()
            .map_err(ice(format!("create block notifier of worker {worker}")))?;
        Ok(WorkerPorts {
            cmd_sub,
            cmd_listener,
            block_pub,
            block_notifier,
        })
    }

    /// Take the next command, if any.
    pub fn try_recv_cmd(&self) -> Result<Option<Sample<Svc, [u64], CmdHeader>>, IpcError> {
        self.cmd_sub.receive().map_err(ice("receive command"))
    }

    /// The listener woken by new commands (for [`crate::hybrid_wait`]).
    pub fn cmd_listener(&self) -> &Listener<Svc> {
        &self.cmd_listener
    }

    /// Loan a block of `words` payload words. The memory is the publisher's shared-memory chunk
    /// (initialised memory: zero-filled by the kernel, or a previous block's content).
    pub fn loan_block(&self, words: usize) -> Result<BlockSampleMut, IpcError> {
        let s = self
            .block_pub
            .loan_slice_uninit(words.max(1))
            .map_err(ice("loan block sample"))?;
        // SAFETY: the chunk lives in a shared-memory mapping which the kernel zero-fills and
        // which only ever holds plain integer data written by previous blocks: every bit
        // pattern is a valid u64, so the memory is initialised.
        Ok(unsafe { s.assume_init() })
    }

    /// Publish a block (stamped with its [`BlockHeader::ready_ns`]) and wake the supervisor.
    pub fn send_block(&self, mut s: BlockSampleMut) -> Result<(), IpcError> {
        s.user_header_mut().ready_ns = crate::services::monotonic_ns();
        s.send().map_err(ice("send block"))?;
        self.block_notifier
            .notify()
            .map_err(ice("notify supervisor"))?;
        Ok(())
    }
}

/// Wakes a worker's own command listener from another thread of the worker: the env threads
/// of a worker whose envs run on threads, when an env is done. The worker's thread then waits
/// on one listener for both commands and finished envs. Wake-ups coalesce: while one is
/// pending (not yet drained by the listener), another costs no system call.
pub struct CmdWaker {
    notifier: Notifier<Svc>,
}

impl std::fmt::Debug for CmdWaker {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("CmdWaker")
    }
}

impl CmdWaker {
    /// A waker of worker `worker`'s command listener.
    pub fn new(node: &Node<Svc>, worker: usize) -> Result<Self, IpcError> {
        let notifier = cmd_event_service(node, worker)?
            .notifier_builder()
            .create()
            .map_err(ice(format!("create command waker of worker {worker}")))?;
        Ok(CmdWaker { notifier })
    }

    /// Wake the listener.
    pub fn wake(&self) -> Result<(), IpcError> {
        self.notifier.notify().map_err(ice("wake the worker"))?;
        Ok(())
    }
}

/// View a block's words as bytes.
pub fn words_as_bytes(w: &[u64]) -> &[u8] {
    // SAFETY: u8 has alignment 1 and every byte of a u64 is initialised.
    unsafe { std::slice::from_raw_parts(w.as_ptr().cast::<u8>(), std::mem::size_of_val(w)) }
}

/// View a block's words as mutable bytes.
pub fn words_as_bytes_mut(w: &mut [u64]) -> &mut [u8] {
    // SAFETY: as above; any byte pattern is a valid u64.
    unsafe { std::slice::from_raw_parts_mut(w.as_mut_ptr().cast::<u8>(), std::mem::size_of_val(w)) }
}
