/* transform.cl: world-space vertices -> clip space (x, y, d, w), d the view-space distance. */

inline float4 st_clip_position(float3 p, __constant StViewConstants* view) {
  __constant const float* m = view->view_proj; /* column-major */
  const float x = m[0] * p.x + m[4] * p.y + m[8] * p.z + m[12];
  const float y = m[1] * p.x + m[5] * p.y + m[9] * p.z + m[13];
  const float w = m[3] * p.x + m[7] * p.y + m[11] * p.z + m[15];
  const float d = view->view_row[0] * p.x + view->view_row[1] * p.y + view->view_row[2] * p.z +
                  view->view_row[3];
  return (float4)(x, y, d, w);
}

__kernel __attribute__((reqd_work_group_size(ST_LINEAR_WG, 1, 1)))
void transform_vertices(__global const float* positions, const uint vertex_count,
                        __constant StViewConstants* view, __global float4* clip) {
  const uint i = get_global_id(0);
  if (i >= vertex_count) return;
  clip[i] = st_clip_position(vload3(i, positions), view);
}
