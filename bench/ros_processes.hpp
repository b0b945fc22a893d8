/// \file
/// Processes for the benchmark programs that run ROS nodes: a child process with its output in a log, stopped with
/// SIGINT (as roslaunch stops a node) by its destructor, and a ROS master of the benchmark's own when none answers.
#pragma once

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace bimanual_skills::bench {

/// True when something accepts TCP connections on localhost:port.
inline bool listening(int port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  if (fd < 0) return false;
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(static_cast<std::uint16_t>(port));
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  const bool ok = ::connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) == 0;
  ::close(fd);
  return ok;
}

/// A child process (a ROS master, a rollout worker) with its output appended to `log`; stopped by the destructor.
class Child {
 public:
  Child(const std::vector<std::string>& argv, const std::string& log) {
    pid_ = ::fork();
    if (pid_ < 0) throw std::runtime_error("cannot fork");
    if (pid_ == 0) {
      const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
      if (fd >= 0) {
        ::dup2(fd, 1);
        ::dup2(fd, 2);
      }
      std::vector<char*> args;
      for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
      args.push_back(nullptr);
      ::execvp(args[0], args.data());
      std::_Exit(127);
    }
  }
  ~Child() {
    if (pid_ <= 0) return;
    ::kill(pid_, SIGINT);
    for (int i = 0; i < 50; ++i) {
      if (::waitpid(pid_, nullptr, WNOHANG) == pid_) return;
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    ::kill(pid_, SIGKILL);
    ::waitpid(pid_, nullptr, 0);
  }
  Child(const Child&) = delete;
  Child& operator=(const Child&) = delete;

 private:
  pid_t pid_ = -1;
};

/// A ROS master for the benchmark: the one at ROS_MASTER_URI if it answers, else a new one on a free port.
inline std::unique_ptr<Child> ensureMaster(const std::string& log, const std::string& program) {
  const char* uri = std::getenv("ROS_MASTER_URI");
  int port = 11311;
  if (uri != nullptr) {
    const std::string text = uri;
    const std::size_t colon = text.rfind(':');
    if (colon != std::string::npos) port = std::atoi(text.c_str() + colon + 1);
  }
  if (listening(port)) return nullptr;
  // A master of its own, on the loopback interface unless ROS_IP or ROS_HOSTNAME says otherwise.
  if (std::getenv("ROS_IP") == nullptr && std::getenv("ROS_HOSTNAME") == nullptr)
    ::setenv("ROS_HOSTNAME", "localhost", 1);
  port = 11711 + static_cast<int>(::getpid() % 1000);
  while (listening(port)) ++port;
  ::setenv("ROS_MASTER_URI", ("http://localhost:" + std::to_string(port)).c_str(), 1);
  auto master =
      std::make_unique<Child>(std::vector<std::string>{"rosmaster", "--core", "-p", std::to_string(port)}, log);
  for (int i = 0; i < 100 && !listening(port); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  if (!listening(port)) throw std::runtime_error("no ROS master answers and rosmaster did not start (see " + log + ")");
  std::printf("%s: started a ROS master on port %d\n", program.c_str(), port);
  return master;
}

}  // namespace bimanual_skills::bench
