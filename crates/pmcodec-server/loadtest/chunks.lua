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

function done(summary, latency, requests)
  io.write(string.format("non-2xx responses: %d, socket errors: connect %d read %d write %d timeout %d\n",
    summary.errors.status, summary.errors.connect, summary.errors.read, summary.errors.write, summary.errors.timeout))
  for _, p in ipairs({50, 90, 99, 99.9}) do
    io.write(string.format("p%g: %.2f ms\n", p, latency:percentile(p) / 1000))
  end
end
