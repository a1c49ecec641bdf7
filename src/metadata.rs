//! Where an image carries its recipe: the PNG text chunk's keyword and the EXR header
//! attribute's name, and the most bytes a recipe may take; below every reader of image
//! headers (`png_header`, `exr_header`) and `recipe`, which says what a recipe holds.

/// The PNG text chunk's keyword and the EXR header attribute's name.
pub const KEY: &str = "tessera-recipe";
/// The most bytes a recipe may take once decompressed: the cover's is 3 KiB. A chunk that
/// inflates beyond this is refused before it is inflated further.
pub const MAX_BYTES: usize = 1 << 20;
