-- wrk: the same few hundred tiles over and over (primed before the run: cache hits).
-- Usage: wrk -s warm.lua URL -- /api/v1/textures/ID/tiles/0 COUNT
function init(args)
  prefix, count, n = args[1], tonumber(args[2]), 0
end
function request()
  n = n + 1
  local i = n % count
  return wrk.format("GET", string.format("%s/%d/%d.jpg", prefix, 300 + i % 20, 300 + math.floor(i / 20)))
end
