// compare benchmark: records the calibration hall (OS1-64, 64 x 1024, 50 frames by default) and
// runs `lidartwin compare` on it, as a user would, several times; prints the median wall time and
// the peak resident memory of the compare process. Plots are excluded (--no-plots): they are
// Python's time, not the analysis'. Target (the compare issue): 50 frames of 64 x 1024 within 15 s
// on 2 cores, peak memory under 2 GB. Also times --refine-pose, --static and --diagnose (the
// diagnose issue's target: within 3 minutes on 50 frames of 64 x 1024; once, it is slow).
//   compare_bench [frames=50] [repeats=3]
#include <sys/resource.h>
#include <sys/wait.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include <unistd.h>

namespace fs = std::filesystem;

namespace {

const std::string kSource = LIDARTWIN_SOURCE_DIR;
const std::string kHall = kSource + "/scenes/calibration_hall.glb";

struct Run {
  double seconds = 0.0;
  double peak_mb = 0.0;
};

// Runs the command in a child and measures it alone: wall time and the child's peak RSS.
Run measure(const std::string& command) {
  const auto start = std::chrono::steady_clock::now();
  const pid_t pid = fork();
  if (pid == 0) {
    execl("/bin/sh", "sh", "-c", command.c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  int status = 0;
  rusage usage{};
  wait4(pid, &status, 0, &usage);
  Run run;
  run.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  run.peak_mb = static_cast<double>(usage.ru_maxrss) / 1024.0;  // kB on Linux
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    std::fprintf(stderr, "compare_bench: failed: %s\n", command.c_str());
    std::exit(1);
  }
  return run;
}

void report(const char* what, const std::string& command, int repeats) {
  std::vector<double> seconds;
  double peak = 0.0;
  for (int i = 0; i < repeats; ++i) {
    const Run run = measure(command);
    seconds.push_back(run.seconds);
    peak = std::max(peak, run.peak_mb);
  }
  std::sort(seconds.begin(), seconds.end());
  std::printf("%-32s median %6.2f s (min %.2f, max %.2f), peak memory %6.0f MB\n", what, seconds[seconds.size() / 2],
              seconds.front(), seconds.back(), peak);
}

}  // namespace

int main(int argc, char** argv) {
  const int frames = argc > 1 ? std::atoi(argv[1]) : 50;
  const int repeats = argc > 2 ? std::atoi(argv[2]) : 3;
  const fs::path dir = fs::temp_directory_path() / ("compare_bench_" + std::to_string(getpid()));
  const std::string binary = LIDARTWIN_BINARY;
  const std::string record = binary + " record --profile os1-64 --scene " + kHall + " --trajectory " + kSource +
                             "/scenes/calibration_hall_static.tum --frames " + std::to_string(frames) +
                             " --seed 1 --out " + (dir / "capture").string() + " >/dev/null";
  measure(record);
  std::printf("compare of %d frames of OS1-64 1024x10 (%d pixels) of the calibration hall, %u cores, %d repeats\n",
              frames, frames * 64 * 1024, std::max(1u, std::thread::hardware_concurrency()), repeats);
  const std::string compare = binary + " compare --capture " + (dir / "capture").string() + " --scene " + kHall +
                              " --profile os1-64 --no-plots --out " + (dir / "out").string() + " >/dev/null";
  report("compare", compare, repeats);
  report("compare --refine-pose", compare + " --refine-pose", repeats);
  report("compare --diagnose", compare + " --diagnose", 1);
  report("compare --static",
         binary + " compare --static --capture " + (dir / "capture").string() + " --profile os1-64 --no-plots --out " +
             (dir / "static").string() + " >/dev/null",
         repeats);
  // Map mode needs a moving sensor: a drive through the plant at 2.5 m/s, 1.7 m above the ground.
  const fs::path drive = dir / "drive.tum";
  std::ofstream(drive) << "0 5 9 1.7 0 0 0 1\n"
                       << 0.1 * frames + 0.5 << " " << 5 + 2.5 * (0.1 * frames + 0.5)
                       << " 9 1.7 0 0 0.0871557 0.9961947\n";
  measure(binary + " record --profile os1-64 --scene " + kSource + "/scenes/plant.glb --trajectory " + drive.string() +
          " --uptime-s 0 --frames " + std::to_string(frames) + " --seed 1 --out " + (dir / "drive").string() +
          " >/dev/null");
  const std::string map = binary + " compare --map --capture " + (dir / "drive" / "capture.pcap").string() +
                          " --metadata " + (dir / "drive" / "metadata.json").string() +
                          " --profile os1-64 --no-plots --out " + (dir / "map").string();
  std::printf("the drive through the plant, %d frames of OS1-64 1024x10:\n", frames);
  report("compare --map (registered)", map + " >/dev/null", repeats);
  report("compare --map --pose (given)", map + " --pose " + (dir / "drive" / "poses.tum").string() + " >/dev/null",
         repeats);
  std::printf(
      "targets: compare of 50 frames within 15 s and 2048 MB (plots excluded); --diagnose within 180 s; --map "
      "within 30 s and 2048 MB\n");
  fs::remove_all(dir);
  return 0;
}
