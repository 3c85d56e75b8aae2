-- wrk script: LOD on demand at random frames and triangle budgets of one asset.
-- ASSET, FRAMES, MIN_TRIS, MAX_TRIS come from the environment (run.sh sets them).
local asset = os.getenv("ASSET") or "horse"
local frames = tonumber(os.getenv("FRAMES") or "48")
local lo = tonumber(os.getenv("MIN_TRIS") or "200")
local hi = tonumber(os.getenv("MAX_TRIS") or "16000")
local counter = 0

function setup(thread)
  counter = counter + 1
  thread:set("seed", counter)
end

function init(args)
  math.randomseed(seed * 7919)
end

function request()
  local f = math.random(0, frames - 1)
  local t = math.random(lo, hi)
  return wrk.format("GET", "/v1/assets/" .. asset .. "/mesh?frame=" .. f .. "&triangles=" .. t .. "&format=bin")
end

local errors = 0
function response(status, headers, body)
  if status ~= 200 then errors = errors + 1 end
end

function done(summary, latency, requests)
  io.write(string.format("non-2xx responses: %d, socket errors: connect %d read %d write %d timeout %d\n",
    summary.errors.status, summary.errors.connect, summary.errors.read, summary.errors.write, summary.errors.timeout))
  for _, p in ipairs({50, 90, 99, 99.9}) do
    io.write(string.format("p%g: %.2f ms\n", p, latency:percentile(p) / 1000))
  end
end
