//! The quadtree walk: visits the nodes of the cut in coding order and codes split flags and
//! leaves. The decoder and the encoder's writer both run [`walk`]; they differ only in their
//! [`Coder`] and [`TreeVisitor`].
//!
//! The image is cut into stripes ([`Header::stripe_width`]) and each stripe into coding tiles
//! of [`CODING_TILE`] pixels (or one tile, the smallest power-of-two square at least one
//! smallest leaf that covers the image, when that is smaller). Stripes are coded left to right;
//! in a stripe, bands of tiles top to bottom; in a band, tiles left to right. Each tile is a
//! quadtree whose children are visited in Z order: top-left, top-right, bottom-left,
//! bottom-right. Nodes entirely outside the image are skipped (nothing is coded for them). A
//! node larger than the largest leaf is split without a flag; a node of the smallest leaf size
//! is a leaf without a flag; every other node codes a split flag.

use crate::colour::{chroma_node, ChromaFrontier, ChromaPatch};
use crate::entropy::Coder;
use crate::error::{DecodeError, PayloadError, SyntaxElement};
use crate::format::{CODING_TILE, DEFAULT_STRIPE, MAX_LEAF_LOG2};
pub use crate::geometry::Node;
use crate::prediction::{Frontier, SamplePrediction};
use crate::syntax::{
    code_chroma, code_chroma_subtree, code_leaf, code_split, reconstruct_chroma, reconstruct_into,
    ChromaContexts, Contexts, ControlCoding, Header, LeafSyntax,
};
use crate::synthesis::Patch;

/// What a node is in the coding order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NodeKind {
    /// Entirely outside the image: not coded.
    Outside,
    /// Split without a flag (larger than the largest leaf).
    ForcedSplit,
    /// A leaf without a flag (smallest leaf size).
    ForcedLeaf,
    /// Carries a split flag.
    Flagged,
}

/// Classifies `node` for a stream with `header`.
pub fn node_kind(header: &Header, node: &Node) -> NodeKind {
    if node.x >= u32::from(header.width) || node.y >= u32::from(header.height) {
        NodeKind::Outside
    } else if node.log2 > header.max_leaf_log2 {
        NodeKind::ForcedSplit
    } else if node.log2 <= header.min_leaf_log2 {
        NodeKind::ForcedLeaf
    } else {
        NodeKind::Flagged
    }
}

/// The two sides of the walk: an encoder supplies decisions, a decoder consumes results.
pub trait TreeVisitor {
    /// Why a visit can fail: the stream's errors, and whatever else the visitor adds (a pixel
    /// sink's).
    type Error: From<DecodeError>;
    /// Encoder: whether `node` is split (called before its flag is coded). Decoders need not
    /// implement it: the flag read from the stream replaces the answer.
    fn split(&mut self, _node: &Node) -> bool {
        false
    }
    /// Encoder: fills in the leaf's syntax elements before they are coded, knowing the pixels
    /// earlier leaves drew (`prediction`). Decoders do nothing.
    fn prepare_leaf<P: SamplePrediction>(
        &mut self,
        _node: &Node,
        _prediction: &P,
        _leaf: &mut LeafSyntax,
    ) {
    }
    /// Called once the leaf is coded, with its reconstruction. The frontier must learn the
    /// leaf's bottom row and right column before the next leaf: [`Frontier::record`] renders
    /// them, or a visitor that draws the whole leaf anyway draws it through
    /// [`Frontier::capture`].
    fn leaf<const STRIPE: usize>(
        &mut self,
        info: &LeafInfo,
        patch: &Patch,
        frontier: &mut Frontier<STRIPE>,
    ) -> Result<(), Self::Error>;

    /// Encoder: fills in chroma plane `plane`'s syntax (0: `Cb`, 1: `Cr`) of the leaf whose
    /// chroma node is `node` before it is coded, knowing the chroma pixels earlier leaves drew
    /// (`prediction`) and the chroma contexts' state (`contexts`). Decoders do nothing.
    fn prepare_chroma<P: SamplePrediction>(
        &mut self,
        _node: &Node,
        _plane: usize,
        _prediction: &P,
        _contexts: &ChromaContexts,
        _leaf: &mut LeafSyntax,
    ) {
    }

    /// Encoder: whether the split node `node` of a colour stream codes the chroma of its whole
    /// subtree (asked only outside such a subtree; its leaves then code no chroma). Decoders
    /// may return anything: the flag read from the stream replaces it.
    fn chroma_subtree(&mut self, _node: &Node) -> bool {
        false
    }

    /// [`TreeVisitor::leaf`] for a leaf of a colour stream, with its chroma (`chroma`: the
    /// leaf's own, or that of the subtree it lies in, whose node covers the leaf) and the
    /// chroma of the leaves before it (`chroma_frontier`, which the walk updates after this
    /// call). By default, the luma leaf alone.
    fn leaf_colour<const STRIPE: usize>(
        &mut self,
        info: &LeafInfo,
        patch: &Patch,
        _chroma: &ChromaPatch,
        frontier: &mut Frontier<STRIPE>,
        _chroma_frontier: &ChromaFrontier<STRIPE>,
    ) -> Result<(), Self::Error> {
        self.leaf(info, patch, frontier)
    }
}

/// The chroma state of a colour stream's walk: the chroma contexts and frontier, and the
/// chroma being drawn.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ChromaState<const STRIPE: usize = DEFAULT_STRIPE> {
    /// Adaptive contexts of the chroma planes.
    pub contexts: ChromaContexts,
    /// Chroma prediction memory.
    pub frontier: ChromaFrontier<STRIPE>,
    /// The chroma of the current leaf, or of the subtree the walk is in.
    pub patch: ChromaPatch,
}

/// What a walk reports about a coded leaf besides its patch.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LeafInfo {
    /// The leaf's node.
    pub node: Node,
    /// Model type index.
    pub model: u8,
    /// Control quantiser index.
    pub cquant: u8,
    /// How the control values were coded.
    pub coding: ControlCoding,
}

/// The adaptive state of the walk: contexts and prediction memory (for stripes of up to
/// `STRIPE` pixels).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct WalkState<const STRIPE: usize = DEFAULT_STRIPE> {
    /// Adaptive contexts.
    pub contexts: Contexts,
    /// Prediction memory.
    pub frontier: Frontier<STRIPE>,
    /// The leaf being drawn: kept here rather than made for each leaf, whose reconstruction
    /// writes every control value the patch's model reads.
    patch: Patch,
}

impl<const STRIPE: usize> WalkState<STRIPE> {
    /// Cleared state (contexts not started, nothing decoded), all zero bits: a decoder clears its
    /// state in place, then sets the contexts with [`Contexts::start`] ([`walk_with`] starts
    /// the frontier). The state at the start of a stream is [`WalkState::default`].
    pub const FRESH: WalkState<STRIPE> = WalkState {
        contexts: Contexts::UNSTARTED,
        frontier: Frontier::EMPTY,
        patch: Patch::CLEARED,
    };
}

/// Codes the whole image of a stream with `header`; returns the final state.
pub fn walk<C: Coder, V: TreeVisitor, const STRIPE: usize>(
    header: &Header,
    coder: &mut C,
    visitor: &mut V,
) -> Result<WalkState<STRIPE>, V::Error> {
    let mut state = WalkState::default();
    walk_with(header, coder, visitor, &mut state)?;
    Ok(state)
}

/// Like [`walk`], with a caller-provided state whose contexts the caller has set (no copy of
/// it is returned). Fails before coding anything if the header's stripes are wider than the
/// state's frontier holds ([`DecodeError::StripeTooWide`]). A colour stream's chroma state is
/// made here, in a frame of its own (`walk_colour`).
pub fn walk_with<C: Coder, V: TreeVisitor, const STRIPE: usize>(
    header: &Header,
    coder: &mut C,
    visitor: &mut V,
    state: &mut WalkState<STRIPE>,
) -> Result<(), V::Error> {
    match header.channels {
        #[cfg(feature = "colour")]
        3 => walk_colour(header, coder, visitor, state),
        1 => walk_planes(header, coder, visitor, state, None),
        other => Err(DecodeError::UnsupportedChannels(other).into()),
    }
}

/// [`walk_with`] for a colour stream: holds the chroma state (its contexts started) while the image
/// is walked. Out of line, so that a grayscale decode's stack has no chroma state.
#[cfg(feature = "colour")]
#[inline(never)]
fn walk_colour<C: Coder, V: TreeVisitor, const STRIPE: usize>(
    header: &Header,
    coder: &mut C,
    visitor: &mut V,
    state: &mut WalkState<STRIPE>,
) -> Result<(), V::Error> {
    // The patch is coded before any leaf reads it.
    let mut chroma = ChromaState::<STRIPE> {
        contexts: ChromaContexts::UNSTARTED,
        frontier: ChromaFrontier::EMPTY,
        patch: ChromaPatch {
            node: Node {
                x: 0,
                y: 0,
                log2: 0,
            },
            planes: [
                crate::colour::ChromaPlane::cleared(),
                crate::colour::ChromaPlane::cleared(),
            ],
        },
    };
    chroma.contexts.start();
    walk_planes(header, coder, visitor, state, Some(&mut chroma))
}

/// The walk of every plane: luma, and chroma when `chroma` is given.
fn walk_planes<C: Coder, V: TreeVisitor, const STRIPE: usize>(
    header: &Header,
    coder: &mut C,
    visitor: &mut V,
    state: &mut WalkState<STRIPE>,
    mut chroma: Option<&mut ChromaState<STRIPE>>,
) -> Result<(), V::Error> {
    let (width, height) = (u32::from(header.width), u32::from(header.height));
    let stripe = header.stripe_width();
    let chroma_ok = match chroma.as_deref_mut() {
        Some(c) => c.frontier.start(width, height, stripe),
        None => true,
    };
    if !chroma_ok || !state.frontier.start(width, height, stripe, header.deblock) {
        return Err(DecodeError::StripeTooWide {
            stripe,
            capacity: Frontier::<STRIPE>::CAPACITY,
        }
        .into());
    }
    let tile_log2 = header.root_log2().min(MAX_LEAF_LOG2);
    let tile = 1u32 << tile_log2;
    // The stripe is a multiple of the coding tile, hence of `tile`. Loops of additions, not
    // `step_by`, whose set-up divides (a routine call on a Cortex-M0).
    let stripe = stripe.max(CODING_TILE);
    let mut x0 = 0;
    while x0 < width {
        let mut y = 0;
        while y < height {
            let mut x = x0;
            while x < width.min(x0 + stripe) {
                let root = Node {
                    x,
                    y,
                    log2: tile_log2,
                };
                walk_tile(header, coder, visitor, state, chroma.as_deref_mut(), root)?;
                x += tile;
            }
            y += tile;
        }
        x0 += stripe;
    }
    Ok(())
}

/// Deepest quadtree in a coding tile: a root of side 2^7 down to leaves of side 2.
const MAX_DEPTH: usize = MAX_LEAF_LOG2 as usize;

/// Depth-first walk of one coding tile in Z order without recursion: the path from the root is
/// one child index per level, and the current node is updated in place.
fn walk_tile<C: Coder, V: TreeVisitor, const STRIPE: usize>(
    header: &Header,
    coder: &mut C,
    visitor: &mut V,
    state: &mut WalkState<STRIPE>,
    mut chroma: Option<&mut ChromaState<STRIPE>>,
    root: Node,
) -> Result<(), V::Error> {
    let mut node = root;
    let mut path = [0u8; MAX_DEPTH];
    let mut depth = 0usize;
    // The depth of the node whose chroma covers its subtree, while the walk is in it.
    let mut subtree: Option<usize> = None;
    loop {
        let kind = node_kind(header, &node);
        let split = match kind {
            NodeKind::Outside => false,
            NodeKind::ForcedSplit => true,
            NodeKind::ForcedLeaf => false,
            NodeKind::Flagged => {
                let mut split = visitor.split(&node);
                code_split(coder, &mut state.contexts, node.log2, &mut split).map_err(lift)?;
                split
            }
        };
        let own_chroma = subtree.is_none();
        if !split && kind != NodeKind::Outside {
            let chroma = chroma.as_deref_mut();
            walk_leaf(coder, visitor, state, chroma, own_chroma, node)?;
        } else if kind == NodeKind::Flagged && own_chroma {
            if let Some(c) = chroma.as_deref_mut() {
                let mut here = visitor.chroma_subtree(&node);
                code_chroma_subtree(coder, &mut c.contexts, &node, &mut here).map_err(lift)?;
                if here {
                    code_chroma_patch(coder, visitor, c, &node).map_err(lift)?;
                    subtree = Some(depth);
                }
            }
        }
        if split {
            // Split nodes are larger than the smallest leaf, so log2 >= 1 here.
            if depth >= MAX_DEPTH || node.log2 == 0 {
                return Err(DecodeError::InvalidData(SyntaxElement::QuadtreeDepth).into());
            }
            path[depth] = 0;
            depth += 1;
            node = node.children()[0];
            continue;
        }
        // Next sibling, climbing while the current node is its parent's last child.
        loop {
            let Some(last) = depth.checked_sub(1) else {
                return Ok(());
            };
            let Some(&c) = path.get(last) else {
                return Ok(());
            };
            let size = node.size();
            let parent = Node {
                x: node.x - u32::from(c & 1) * size,
                y: node.y - u32::from(c >> 1) * size,
                log2: node.log2 + 1,
            };
            if c < 3 {
                path[last] = c + 1;
                node = parent.children()[usize::from(c + 1)];
                break;
            }
            node = parent;
            depth = last;
            if subtree == Some(depth) {
                subtree = None;
            }
        }
    }
}

/// A payload error as the visitor's error (out of the payload's hot path, where errors are
/// one byte).
fn lift<E: From<DecodeError>>(e: PayloadError) -> E {
    DecodeError::from(e).into()
}

/// A leaf's reconstruction and drawing: out of line, so that the patch is not part of the walk's
/// own frame. A colour stream's leaf codes its own chroma when `own_chroma` (it is not in a
/// subtree whose chroma is coded).
#[inline(never)]
fn walk_leaf<C: Coder, V: TreeVisitor, const STRIPE: usize>(
    coder: &mut C,
    visitor: &mut V,
    state: &mut WalkState<STRIPE>,
    chroma: Option<&mut ChromaState<STRIPE>>,
    own_chroma: bool,
    node: Node,
) -> Result<(), V::Error> {
    let mut info = LeafInfo {
        node,
        model: 0,
        cquant: 0,
        coding: ControlCoding::Dpcm,
    };
    code_leaf_patch(coder, visitor, state, &mut info).map_err(lift)?;
    let WalkState {
        frontier, patch, ..
    } = state;
    match chroma {
        None => visitor.leaf(&info, patch, frontier),
        Some(chroma) => colour_leaf(coder, visitor, chroma, own_chroma, &info, patch, frontier),
    }
}

/// The chroma of a colour stream's leaf, coded and reconstructed (when `own_chroma`, else the
/// subtree's is drawn), and drawn with its luma. Out of line, so that a grayscale decode's
/// leaf frame holds no chroma.
#[inline(never)]
fn colour_leaf<C: Coder, V: TreeVisitor, const STRIPE: usize>(
    coder: &mut C,
    visitor: &mut V,
    chroma: &mut ChromaState<STRIPE>,
    own_chroma: bool,
    info: &LeafInfo,
    patch: &Patch,
    frontier: &mut Frontier<STRIPE>,
) -> Result<(), V::Error> {
    if own_chroma {
        code_chroma_patch(coder, visitor, chroma, &info.node).map_err(lift)?;
    }
    visitor.leaf_colour(info, patch, &chroma.patch, frontier, &chroma.frontier)?;
    chroma
        .frontier
        .record(&chroma.patch, &chroma_node(&info.node));
    Ok(())
}

/// The two chroma planes of the node `node` (a leaf, or a node whose chroma covers its
/// subtree) of a colour stream, coded and reconstructed into `chroma.patch`. Out of line, like
/// [`code_leaf_patch`].
#[inline(never)]
fn code_chroma_patch<C: Coder, V: TreeVisitor, const STRIPE: usize>(
    coder: &mut C,
    visitor: &mut V,
    chroma: &mut ChromaState<STRIPE>,
    node: &Node,
) -> Result<(), PayloadError> {
    let cnode = chroma_node(node);
    let ChromaState {
        contexts,
        frontier,
        patch,
    } = chroma;
    patch.node = cnode;
    for (p, plane) in patch.planes.iter_mut().enumerate() {
        let mut leaf = LeafSyntax::default();
        let prediction = frontier.plane(p);
        visitor.prepare_chroma(&cnode, p, &prediction, contexts, &mut leaf);
        code_chroma(coder, contexts, &cnode, &prediction, &mut leaf)?;
        reconstruct_chroma(&leaf, cnode.log2, plane)?;
    }
    Ok(())
}

/// A leaf's syntax, coded and reconstructed into `patch`, and what the walk reports about it
/// into `info` (whose node is the leaf's). Out of line, so that the syntax elements are gone
/// from the stack while the patch is drawn.
#[inline(never)]
fn code_leaf_patch<C: Coder, V: TreeVisitor, const STRIPE: usize>(
    coder: &mut C,
    visitor: &mut V,
    state: &mut WalkState<STRIPE>,
    info: &mut LeafInfo,
) -> Result<(), PayloadError> {
    let node = info.node;
    let mut leaf = LeafSyntax::default();
    visitor.prepare_leaf(&node, &state.frontier, &mut leaf);
    code_leaf(
        coder,
        &mut state.contexts,
        &node,
        &state.frontier,
        &mut leaf,
    )?;
    reconstruct_into(&leaf, node.log2, &mut state.patch)?;
    info.model = leaf.model;
    info.cquant = leaf.cquant;
    info.coding = leaf.coding;
    Ok(())
}
