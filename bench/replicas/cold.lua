-- wrk: distinct level-0 tiles of one texture, so that every request misses every cache.
-- Usage: wrk -s cold.lua URL -- /api/v1/textures/ID/tiles/0 TILES_ACROSS
local threads = 0
function setup(thread)
  thread:set("tid", threads)
  threads = threads + 1
  thread:set("stride", 16)
end
function init(args)
  prefix, across, n = args[1], tonumber(args[2]), 0
end
function request()
  local i = n * stride + tid
  n = n + 1
  return wrk.format("GET", string.format("%s/%d/%d.jpg", prefix, i % across, math.floor(i / across) % across))
end
