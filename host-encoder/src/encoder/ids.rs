//! Typed indices into the format's tables: a model type, a control quantiser. The syntax ([`LeafSyntax`]) carries them as raw bytes; the encoder keeps them
//! apart by type and converts at that boundary. Each is one byte (`#[repr(transparent)]`), as
//! they sit in per-candidate vectors.
//!
//! Bottom layer of the encoder: uses nothing else of it.

use decoder_core::internal::model::{ModelType, MODELS, MODEL_COUNT};
use decoder_core::internal::syntax::control::{
    CONTROL_QUANTISERS, CONTROL_STEPS, QUANTISERS_BY_STEP,
};
use decoder_core::internal::syntax::{models_for_block, step_group, LeafSyntax};

/// A model type: an index into [`MODELS`] (the 'model' syntax element).
#[repr(transparent)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct ModelId(u8);

impl ModelId {
    /// Model `index`; panics if the format has no such model.
    pub const fn new(index: u8) -> ModelId {
        assert!((index as usize) < MODEL_COUNT, "no such model");
        ModelId(index)
    }

    /// The syntax element's value.
    pub const fn get(self) -> u8 {
        self.0
    }

    /// The index as a `usize`, for tables by model.
    pub const fn index(self) -> usize {
        self.0 as usize
    }

    /// The model type.
    pub const fn model(self) -> ModelType {
        MODELS[self.0 as usize]
    }

    /// The models the format allows on blocks of side `2^log2`, in the syntax's order.
    pub fn for_block(log2: u8) -> impl Iterator<Item = ModelId> {
        let (models, count) = models_for_block(log2);
        (0..count).map(move |i| ModelId(models[i]))
    }
}

/// A short list of distinct models (a node's fits, by their models), held inline: a boxed list
/// cost every analysed node a heap allocation of its own.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Models {
    ids: [ModelId; MODEL_COUNT],
    len: u8,
}

impl Models {
    /// No model.
    pub const fn none() -> Models {
        Models {
            ids: [ModelId(0); MODEL_COUNT],
            len: 0,
        }
    }

    /// How many models.
    pub fn len(&self) -> usize {
        usize::from(self.len)
    }

    /// The models, in order.
    pub fn as_slice(&self) -> &[ModelId] {
        &self.ids[..self.len()]
    }
}

impl core::ops::Index<usize> for Models {
    type Output = ModelId;

    fn index(&self, i: usize) -> &ModelId {
        &self.as_slice()[i]
    }
}

impl FromIterator<ModelId> for Models {
    /// Panics past [`MODEL_COUNT`] models (a node has one fit per model at most).
    fn from_iter<I: IntoIterator<Item = ModelId>>(iter: I) -> Models {
        let mut models = Models::none();
        for id in iter {
            models.ids[models.len()] = id;
            models.len += 1;
        }
        models
    }
}

/// A control quantiser, held as its rank among the steps (0 the finest), so that the order of
/// the ids is the order of their steps; [`ControlQuantiserId::get`] is its 'cquant' value.
#[repr(transparent)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct ControlQuantiserId(u8);

impl ControlQuantiserId {
    /// The control quantiser of rank `rank` (0 the finest step); panics if the format has no
    /// such quantiser.
    #[cfg(test)]
    pub const fn new(rank: u8) -> ControlQuantiserId {
        assert!(
            (rank as usize) < CONTROL_QUANTISERS,
            "no such control quantiser"
        );
        ControlQuantiserId(rank)
    }

    /// Every control quantiser, finest step first.
    pub fn all() -> impl DoubleEndedIterator<Item = ControlQuantiserId> {
        (0..CONTROL_QUANTISERS as u8).map(ControlQuantiserId)
    }

    /// Its rank among the steps, 0 the finest.
    pub const fn rank(self) -> u8 {
        self.0
    }

    /// The syntax element's value.
    pub const fn get(self) -> u8 {
        QUANTISERS_BY_STEP[self.0 as usize]
    }

    /// Its step, in sample units (1/16 grey level).
    pub const fn step(self) -> i32 {
        CONTROL_STEPS[self.get() as usize]
    }

    /// Its group of steps, which selects the residuals' contexts.
    pub fn step_group(self) -> usize {
        step_group(self.get())
    }
}

/// The leaf syntax of `model` with control quantiser `cq`, every index zero: where the typed
/// indices become the syntax's bytes.
pub fn leaf_syntax(
    model: ModelId,
    cq: ControlQuantiserId,
    coding: decoder_core::ControlCoding,
) -> LeafSyntax {
    LeafSyntax {
        model: model.get(),
        cquant: cq.get(),
        coding,
        ..LeafSyntax::default()
    }
}

macro_rules! display_as_number {
    ($($id:ty),*) => {$(
        impl std::fmt::Display for $id {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                write!(f, "{}", self.0)
            }
        }
    )*};
}

// As the syntax element's value.
display_as_number!(ModelId, ControlQuantiserId);

#[cfg(test)]
mod tests {
    use super::*;

    /// The typed indices cost no more than the bytes they wrap.
    #[test]
    fn ids_are_one_byte() {
        assert_eq!(std::mem::size_of::<ModelId>(), 1);
        assert_eq!(std::mem::size_of::<ControlQuantiserId>(), 1);
        assert_eq!(ControlQuantiserId::all().count(), CONTROL_QUANTISERS);
    }
}
