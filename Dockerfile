# lipsyncd in a container: a multi-stage build on Debian 12.
#   docker build -t lipsyncd .          # or: podman build
#   docker run -p 50051:50051 lipsyncd
# No container engine runs on the project's machines: deploy/prove-dockerfile.sh performs these
# same steps in a debootstrap'ed Debian 12 chroot and runs the built server in it (docs/deploy.md).

# --- build: the toolchain and the -dev packages --------------------------------------------------
FROM debian:12 AS build
RUN apt-get update \
 && DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends \
      build-essential cmake ninja-build nlohmann-json3-dev libeigen3-dev libspdlog-dev libboost-dev \
      libgrpc++-dev protobuf-compiler-grpc libprotobuf-dev protobuf-compiler libssl-dev \
      libespeak-ng-dev libpocketsphinx-dev libsphinxbase-dev libcli11-dev libnghttp2-dev \
 && rm -rf /var/lib/apt/lists/*
WORKDIR /src
COPY CMakeLists.txt ./
COPY cmake cmake
COPY core core
COPY proto proto
COPY server server
COPY clients clients
COPY data data
COPY docs docs
COPY deploy deploy
COPY README.md ./
RUN cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DCMAKE_INSTALL_PREFIX=/usr \
      -DLIPSYNC_BUILD_TESTS=OFF -DLIPSYNC_BUILD_BENCHMARKS=OFF -DLIPSYNC_BUILD_PYTHON=OFF \
 && cmake --build build --target lipsyncd lipsync \
 && DESTDIR=/staging cmake --install build --component server

# --- runtime: only the shared libraries lipsyncd links (espeak-ng and its data: Speak) ----------
FROM debian:12-slim AS runtime
RUN apt-get update \
 && DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends \
      libgrpc++1.51 libprotobuf32 libspdlog1.10 libfmt9 ca-certificates \
      libespeak-ng1 espeak-ng-data libpocketsphinx3 libsphinxbase3 libnghttp2-14 \
 && rm -rf /var/lib/apt/lists/* \
 && useradd --system --uid 10001 --no-create-home --shell /usr/sbin/nologin lipsyncd
COPY --from=build /staging/usr/bin/lipsyncd /staging/usr/bin/lipsync /usr/bin/
COPY --from=build /staging/usr/share/lipsync /usr/share/lipsync
USER 10001:10001
# Containers configure through the environment: every flag has its LIPSYNCD_* variable.
ENV LIPSYNCD_LISTEN=0.0.0.0:50051 \
    LIPSYNCD_DRAIN_DEADLINE_MS=30000
EXPOSE 50051
# The gRPC health protocol (grpc.health.v1), asked by the lipsync CLI in the image: NOT_SERVING
# while draining. Kubernetes asks it itself (deploy/kubernetes/lipsyncd.yaml: grpc probes).
HEALTHCHECK --interval=10s --timeout=3s --start-period=5s --retries=3 \
  CMD ["/usr/bin/lipsync", "health", "--server", "127.0.0.1:50051", "--timeout", "2"]
STOPSIGNAL SIGTERM
ENTRYPOINT ["/usr/bin/lipsyncd"]
