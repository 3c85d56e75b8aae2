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

dofile((os.getenv("LOADTEST_DIR") or ".") .. "/report.lua")
