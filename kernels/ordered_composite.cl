/* ordered_composite.cl: what the ordered composites share, the cells composite
 * (cells_composite.cl) and the octree resolve (octree_resolve.cl): a pixel's running result,
 * composited fragment by fragment in visibility order and kept between batches in a per-pixel
 * accumulator; the records that carry their colour; and the screen blocks a launch's
 * work-groups or serial work-items take their tiles from. */

typedef struct {
  float3 colour;
  float transmittance;
  int inside;      /* translucency: entering minus leaving fragments so far */
  float last_depth;
  float3 ray_dir;  /* unit pixel ray */
  float ray_len;   /* path length per unit of view distance */
  int x, y;        /* the pixel (texturing) */
  uint begin_count; /* the fragments composited at the pixel before this batch */
} StCellsPixel;

inline void st_cells_composite(StCellsPixel* px, ulong word, __global const StTriSetup* records,
                               __global const float4* record_color,
                               __global const float4* record_normal,
                               __global const StTexTriangle* tex_tris, __global const uint* atlas,
                               __constant StViewConstants* view) {
  const uint rec = (uint)(word & 0xFFFFFFFFul);
  const float depth = as_float((uint)(word >> 32));
  float4 c = record_color[rec];
  if (view->textured)
    c *= st_fragment_texel(tex_tris, atlas, view, records[rec].source, px->x, px->y);
  if (view->effect == ST_EFFECT_TRANSLUCENCY) {
    if (px->inside > 0)
      px->transmittance *= exp(-view->sigma * (depth - px->last_depth) * px->ray_len);
    const float r = st_schlick_reflectance(dot(record_normal[rec].xyz, px->ray_dir));
    px->colour += px->transmittance * r * c.xyz;
    px->transmittance *= 1.0f - r;
    if (records[rec].flags & ST_TRI_FRONT_FACING) ++px->inside;
    else if (px->inside > 0) --px->inside;
    px->last_depth = depth;
  } else {
    st_composite_under(&px->colour, &px->transmittance, c);
  }
}

/* With colour_in_record (a frame whose composite reads no depth: cells_composite_serial's plain
 * tiles, no merged group), a record carries its flat colour in place of its depth planes, which
 * no reader of the frame needs: the composite then reads one cache line per record, not a
 * record and a colour (builtin:spheres:96 at 1024x1024, composite -16 ms), and setup writes no
 * colour apart. */
inline __attribute__((always_inline)) void st_cells_colour_in_record(StTriSetup* r,
                                                                     const float4 colour) {
  r->dw0 = colour.x;
  r->dw_dx = colour.y;
  r->dw_dy = colour.z;
  r->iw0 = colour.w;
}
/* The colour st_cells_colour_in_record put in record r. */
inline float4 st_cells_record_colour(__global const StTriSetup* r) {
  return (float4)(r->dw0, r->dw_dx, r->dw_dy, r->iw0);
}

/* A pixel's running result at the start of a batch: fresh in the first batch (translucency's
 * inside count and last depth taken from accum_extra when first_batch is
 * ST_FIRST_BATCH_SEEDED), else read back from the accumulator (with its fragment count so far,
 * *depth_count). With background_filled, only a pixel an earlier batch composited a fragment at
 * (a non-zero count: the background fill zeroed them) has an accumulator to read. */
inline StCellsPixel st_cells_pixel_begin(int x, int y, bool inside_image, uint pixel,
                                         int first_batch, int background_filled,
                                         __constant StViewConstants* view,
                                         __global const ushort4* accum,
                                         __global const float2* accum_extra,
                                         __global const uint* pixel_fragments, uint* depth_count) {
  StCellsPixel px;
  px.colour = (float3)(0.0f);
  px.transmittance = 1.0f;
  px.inside = 0;
  px.last_depth = 0.0f;
  px.x = x;
  px.y = y;
  px.ray_dir = (float3)(0.0f);
  px.ray_len = 1.0f;
  if (view->effect == ST_EFFECT_TRANSLUCENCY) { /* only translucency follows the ray */
    const float ndc_x = (((float)x + 0.5f) / (float)view->width) * 2.0f - 1.0f;
    const float ndc_y = 1.0f - (((float)y + 0.5f) / (float)view->height) * 2.0f;
    const float3 fwd = (float3)(view->forward[0], view->forward[1], view->forward[2]);
    const float3 right = (float3)(view->right[0], view->right[1], view->right[2]);
    const float3 up = (float3)(view->up[0], view->up[1], view->up[2]);
    const float3 dir =
        fwd + right * (ndc_x * view->ray_tan[0]) + up * (ndc_y * view->ray_tan[1]);
    px.ray_len = length(dir);
    px.ray_dir = dir / px.ray_len;
  }
  *depth_count = 0;
  const uint so_far = !first_batch && inside_image ? pixel_fragments[pixel] : 0u;
  if (!first_batch && inside_image && (so_far != 0 || !background_filled)) {
    const float4 a = convert_float4(accum[pixel]) * (1.0f / 65535.0f);
    px.colour = a.xyz;
    px.transmittance = a.w;
    if (view->effect == ST_EFFECT_TRANSLUCENCY) {
      const float2 e = accum_extra[pixel];
      px.inside = (int)e.x;
      px.last_depth = e.y;
    }
    *depth_count = so_far;
  } else if (first_batch == ST_FIRST_BATCH_SEEDED && inside_image &&
             view->effect == ST_EFFECT_TRANSLUCENCY) {
    /* A share of a distributed frame: the ray enters this share's box already inside this
     * many shells, absorbing from the box's entry depth on. */
    const float2 e = accum_extra[pixel];
    px.inside = (int)e.x;
    px.last_depth = e.y;
  }
  px.begin_count = *depth_count;
  return px;
}

/* A pixel's result at the end of a batch: the image in the last batch, else the accumulator;
 * and its running fragment count (the depth complexity after the last batch). With
 * background_filled every batch writes the image of the pixels it composited a fragment at
 * (and the accumulator too unless it is the last), and leaves the others alone. */
inline void st_cells_pixel_end(const StCellsPixel* px, bool inside_image, uint pixel,
                               int last_batch, int background_filled,
                               __constant StViewConstants* view, __global ushort4* accum,
                               __global float2* accum_extra, __global uchar4* image,
                               __global uint* pixel_fragments, uint depth_count) {
  if (!inside_image) return;
  if (background_filled && depth_count == px->begin_count) return; /* nothing composited */
  if (last_batch || background_filled) {
    const float3 bg = st_background(view, px->x, px->y);
    image[pixel] = st_pack_rgba8(px->colour + px->transmittance * bg);
  }
  if (!last_batch) {
    const float3 c = px->colour; /* (float4) by components: common.cl */
    const float4 a = clamp((float4)(c.x, c.y, c.z, px->transmittance), 0.0f, 1.0f);
    accum[pixel] = convert_ushort4_sat_rte(a * 65535.0f);
    if (view->effect == ST_EFFECT_TRANSLUCENCY)
      st_store_float2(accum_extra, pixel, (float2)((float)px->inside, px->last_depth));
  }
  pixel_fragments[pixel] = depth_count;
}

/* Bin list range [begin, end) of tile `tile` in the ordered binner's tile x chunk table (empty
 * for an invalid tile). */
inline void st_chunked_tile_range(__global const uint* chunk_offsets, uint chunks, uint bin_capacity,
                                  bool tile_valid, uint tile, uint* begin, uint* end) {
  *begin = tile_valid ? min(chunk_offsets[tile * chunks], bin_capacity) : 0u;
  *end = tile_valid ? min(chunk_offsets[(tile + 1) * chunks], bin_capacity) : 0u;
}

/* Tile `sub` of the block (block_x, block_y) of ST_CELLS_BLOCK_TILES^2 tiles, row by row: its
 * coordinates, and whether it lies on the image. */
inline bool st_block_tile(uint block_x, uint block_y, uint sub, uint tiles_x, uint tiles_y,
                          uint* tile_x, uint* tile_y) {
  *tile_x = block_x * ST_CELLS_BLOCK_TILES + sub % ST_CELLS_BLOCK_TILES;
  *tile_y = block_y * ST_CELLS_BLOCK_TILES + sub / ST_CELLS_BLOCK_TILES;
  return *tile_x < tiles_x && *tile_y < tiles_y;
}

/* Tile `sub` of the block (block_x, block_y): its coordinates, whether it lies on the image
 * (`valid`) and its bin list range [begin, end) (empty for a tile off the image). */
typedef struct {
  uint x, y, begin, end;
  int valid;
} StBlockTile;

inline StBlockTile st_block_tile_at(__global const uint* chunk_offsets, uint chunks,
                                    uint bin_capacity, uint tiles_x, uint tiles_y, uint block_x,
                                    uint block_y, uint sub) {
  StBlockTile t;
  t.valid = st_block_tile(block_x, block_y, sub, tiles_x, tiles_y, &t.x, &t.y);
  st_chunked_tile_range(chunk_offsets, chunks, bin_capacity, t.valid, t.y * tiles_x + t.x,
                        &t.begin, &t.end);
  return t;
}

/* How many tiles of the block (block_x, block_y) of ST_CELLS_BLOCK_TILES^2 tiles a work-group
 * walks: all of them, or none when the host wrote the background first (background_filled) and
 * no tile of the block has a bin entry. PoCL runs the code between
 * barriers as loops over the work-items with their state in memory, which made such blocks most
 * of the cost of a sparse frame. A block walked zero times still goes through the barriers of
 * its group report: a return before them made PoCL 3.1 miscount the group's totals (64 times
 * the fragments). */
inline uint st_block_tile_count(int background_filled, __global const uint* chunk_offsets,
                                uint chunks, uint tiles_x, uint tiles_y, uint bin_capacity,
                                uint block_x, uint block_y) {
  const uint all = ST_CELLS_BLOCK_TILES * ST_CELLS_BLOCK_TILES;
  if (!background_filled) return all;
  for (uint sub = 0; sub < all; ++sub) {
    const StBlockTile t = st_block_tile_at(chunk_offsets, chunks, bin_capacity, tiles_x, tiles_y,
                                           block_x, block_y, sub);
    if (t.begin != t.end) return all;
  }
  return 0u;
}

/* How the serial composites (a work-item alone per block of tiles, for CPUs) share a launch's
 * blocks: the launch has one work-item per compute unit, and they claim the range's blocks
 * (block_range: first block x, y, then blocks across and down) in raster order from a counter,
 * in runs that shrink as the range runs out (guided: each a 2 x work-items'th of what is left,
 * at least ST_CELLS_BLOCK_RUN), so each draws long runs of neighbouring blocks, which share
 * records, while much is left, and they finish together however the work lies on the screen.
 * As work-groups of one block, PoCL dealt them to its threads unevenly (the cells composite on
 * the horse at 1024x1024, still 4.8 -> 4.2 ms, drawn with an earlier view's order 6.1 -> 5.3);
 * fixed runs of eight blocks balanced as well but parted neighbours (bunny, spot and
 * cheburashka 5-8% slower).
 *   StBlockDeal deal = st_block_deal_begin();
 *   while (st_block_deal_next(&deal, block_range, counter, &block_x, &block_y)) { ... } */
#define ST_CELLS_BLOCK_RUN 8u
typedef struct {
  uint left;        /* blocks left in the current run */
  uint column, row; /* the next block's place in the range */
} StBlockDeal;

inline StBlockDeal st_block_deal_begin(void) {
  StBlockDeal d;
  d.left = d.column = d.row = 0;
  return d;
}

inline bool st_block_deal_next(StBlockDeal* d, const uint4 block_range, __global ulong* counter,
                               uint* block_x, uint* block_y) {
  if (d->left == 0) { /* the next run: claim k starts where claims 0..k-1 ended */
    const uint blocks = block_range.z * block_range.w;
    const uint claim = (uint)st_counter_claim(counter, 1);
    const uint share = 2u * (uint)get_global_size(0);
    uint start = 0, size = 0;
    for (uint k = 0; start < blocks; ++k) {
      size = max(ST_CELLS_BLOCK_RUN, (blocks - start) / share);
      if (k == claim) break;
      start += size;
    }
    if (start >= blocks) return false;
    d->left = min(size, blocks - start);
    /* Its first block's row and column by subtraction: a division and its remainder make the
     * compiler insert a `freeze`, which Oclgrind's uninitialized-value check cannot run. */
    d->column = start;
    d->row = 0;
    while (d->column >= block_range.z) {
      d->column -= block_range.z;
      ++d->row;
    }
  }
  *block_x = block_range.x + d->column;
  *block_y = block_range.y + d->row;
  --d->left;
  if (++d->column == block_range.z) {
    d->column = 0;
    ++d->row;
  }
  return true;
}

