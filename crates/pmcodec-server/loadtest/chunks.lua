-- wrk script: range requests for the chunks of random frames of one asset's container, as a
-- streaming client makes them. CHUNKS is a file of "offset length" lines and FILE the
-- container's immutable URL (run.sh writes both from the asset's index).
local file = os.getenv("FILE")
local ranges = {}
for line in io.lines(os.getenv("CHUNKS")) do
  local off, len = line:match("(%d+) (%d+)")
  ranges[#ranges + 1] = { tonumber(off), tonumber(len) }
end

function request()
  local r = ranges[math.random(1, #ranges)]
  return wrk.format("GET", file, { ["Range"] = "bytes=" .. r[1] .. "-" .. (r[1] + r[2] - 1) })
end

dofile((os.getenv("LOADTEST_DIR") or ".") .. "/report.lua")
