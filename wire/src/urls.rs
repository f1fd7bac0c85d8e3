//! The URL templates of what clients fetch, relative to the server's root (`{file}` is
//! `{y}.{format}`), and the paths they give.

/// A tile of the tile pyramid.
pub const TILE: &str = "/api/v1/textures/{id}/tiles/{level}/{x}/{file}";
/// A bordered page of a level's page grid.
pub const PAGE: &str = "/api/v1/textures/{id}/pages/{level}/{x}/{file}";
/// A metatile: the aligned block of tiles ([`crate::levels::metatile_tiles`] a side) whose
/// tile (`x`, `y`) is tile (`x·n`, `y·n`) of the level, answered as [`crate::frame`]s.
pub const METATILE: &str = "/api/v1/textures/{id}/metatiles/{level}/{x}/{file}";
/// A page metatile: the aligned block of bordered pages ([`crate::levels::metatile_tiles`] of
/// the page size a side) whose page (`x`, `y`) is page (`x·n`, `y·n`) of the level's page grid,
/// answered as [`crate::frame`]s.
pub const PAGE_METATILE: &str = "/api/v1/textures/{id}/page-metatiles/{level}/{x}/{file}";
/// Many tiles or pages at once (the `tiles` query), answered as [`crate::frame`]s.
pub const BATCH: &str = "/api/v1/textures/{id}/tiles";

/// The path of tile (`level`, `x`, `y`) of texture `id` in format `ext`.
pub fn tile_path(id: &str, level: u32, x: u32, y: u32, ext: &str) -> String {
    fill(TILE, id, level, x, y, ext)
}

/// The path of page (`level`, `x`, `y`) of texture `id` in format `ext` (its size, border and
/// codec go in the query).
pub fn page_path(id: &str, level: u32, x: u32, y: u32, ext: &str) -> String {
    fill(PAGE, id, level, x, y, ext)
}

/// The path of metatile (`level`, `x`, `y`) of texture `id` in format `ext`.
pub fn metatile_path(id: &str, level: u32, x: u32, y: u32, ext: &str) -> String {
    fill(METATILE, id, level, x, y, ext)
}

/// The path of page metatile (`level`, `x`, `y`) of texture `id` in format `ext` (its page
/// size, border and codec go in the query).
pub fn page_metatile_path(id: &str, level: u32, x: u32, y: u32, ext: &str) -> String {
    fill(PAGE_METATILE, id, level, x, y, ext)
}

/// The path of a batch of texture `id` (its items and format go in the query).
pub fn batch_path(id: &str) -> String {
    BATCH.replace("{id}", id)
}

fn fill(template: &str, id: &str, level: u32, x: u32, y: u32, ext: &str) -> String {
    template
        .replace("{id}", id)
        .replace("{level}", &level.to_string())
        .replace("{x}", &x.to_string())
        .replace("{file}", &format!("{y}.{ext}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_fill_the_templates() {
        assert_eq!(tile_path("ab", 3, 4, 5, "png"), "/api/v1/textures/ab/tiles/3/4/5.png");
        assert_eq!(page_path("ab", 0, 1, 2, "ktx2"), "/api/v1/textures/ab/pages/0/1/2.ktx2");
        assert_eq!(metatile_path("ab", 2, 0, 1, "jpg"), "/api/v1/textures/ab/metatiles/2/0/1.jpg");
        assert_eq!(page_metatile_path("ab", 1, 2, 3, "rgba"), "/api/v1/textures/ab/page-metatiles/1/2/3.rgba");
        assert_eq!(batch_path("ab"), "/api/v1/textures/ab/tiles");
    }
}
