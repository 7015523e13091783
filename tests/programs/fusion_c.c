/* A plain C program on rcl, as a user would write it (no cosim code): the C twin of
 * fusion.py. It keeps the latest std_msgs/Int64 of its inputs 'a' and 'b' and publishes
 * a * 1000 + b (or -1 while an input has not arrived) on 'out', from a 10 Hz timer on sim
 * time (the default) or in b's callback.
 *
 * Usage: fusion_c [ORDER [TRIGGER]] --ros-args ...
 *   ORDER    'ab' (default) or 'ba': the order its wait set lists the two inputs in
 *   TRIGGER  'timer' (default) or 'b'
 * Its sim time is its own time source: it subscribes to /clock and sets the ROS time of its
 * clock from every Clock it takes (what rclpy and rclcpp do with use_sim_time). */
#include <signal.h>
#include <stdio.h>
#include <string.h>

#include "rcl/error_handling.h"
#include "rcl/rcl.h"
#include "rcl/time.h"
#include "rcl/timer.h"
#include "rcl/wait.h"
#include "rosgraph_msgs/msg/clock.h"
#include "rosidl_runtime_c/message_type_support_struct.h"
#include "std_msgs/msg/int64.h"

#define PERIOD_NS 100000000LL

static volatile sig_atomic_t stop;

static void on_signal(int sig)
{
  (void)sig;
  stop = 1;
}

static int check(rcl_ret_t ret, const char * what)
{
  if (ret != RCL_RET_OK) {
    fprintf(stderr, "fusion_c: %s failed: %s\n", what, rcl_get_error_string().str);
    rcl_reset_error();
    return 1;
  }
  return 0;
}

/* Publish a * 1000 + b, or -1 while an input has not arrived; 1 on failure. */
static int publish(const rcl_publisher_t * pub, int have_both, int64_t a, int64_t b)
{
  std_msgs__msg__Int64 out = {have_both ? a * 1000 + b : -1};
  return check(rcl_publish(pub, &out, NULL), "rcl_publish");
}

int main(int argc, char ** argv)
{
  const char * order = argc > 1 && strcmp(argv[1], "--ros-args") ? argv[1] : "ab";
  const char * trigger = argc > 2 && strcmp(argv[2], "--ros-args") ? argv[2] : "timer";
  int timer_mode = strcmp(trigger, "b") != 0;
  signal(SIGINT, on_signal);
  signal(SIGTERM, on_signal);

  rcl_allocator_t alloc = rcl_get_default_allocator();
  rcl_init_options_t init_options = rcl_get_zero_initialized_init_options();
  rcl_context_t context = rcl_get_zero_initialized_context();
  if (check(rcl_init_options_init(&init_options, alloc), "rcl_init_options_init") ||
    check(rcl_init(argc, (const char * const *)argv, &init_options, &context), "rcl_init"))
  {
    return 1;
  }
  rcl_node_t node = rcl_get_zero_initialized_node();
  rcl_node_options_t node_options = rcl_node_get_default_options();
  if (check(rcl_node_init(&node, "fusion_c", "", &context, &node_options), "rcl_node_init")) {
    return 1;
  }

  const rosidl_message_type_support_t * int64 = ROSIDL_GET_MSG_TYPE_SUPPORT(std_msgs, msg, Int64);
  const rosidl_message_type_support_t * clock_type =
    ROSIDL_GET_MSG_TYPE_SUPPORT(rosgraph_msgs, msg, Clock);
  rcl_subscription_t clock_sub = rcl_get_zero_initialized_subscription();
  rcl_subscription_t sub_a = rcl_get_zero_initialized_subscription();
  rcl_subscription_t sub_b = rcl_get_zero_initialized_subscription();
  rcl_subscription_options_t sub_options = rcl_subscription_get_default_options();
  rcl_publisher_t pub = rcl_get_zero_initialized_publisher();
  rcl_publisher_options_t pub_options = rcl_publisher_get_default_options();
  if (check(rcl_subscription_init(&clock_sub, &node, clock_type, "/clock", &sub_options),
    "clock subscription") ||
    check(rcl_subscription_init(&sub_a, &node, int64, "a", &sub_options), "subscription a") ||
    check(rcl_subscription_init(&sub_b, &node, int64, "b", &sub_options), "subscription b") ||
    check(rcl_publisher_init(&pub, &node, int64, "out", &pub_options), "publisher"))
  {
    return 1;
  }

  rcl_clock_t clock;
  rcl_timer_t timer = rcl_get_zero_initialized_timer();
  if (check(rcl_ros_clock_init(&clock, &alloc), "rcl_ros_clock_init") ||
    check(rcl_enable_ros_time_override(&clock), "rcl_enable_ros_time_override") ||
    check(rcl_set_ros_time_override(&clock, 0), "rcl_set_ros_time_override") ||
    check(rcl_timer_init2(&timer, &clock, &context, PERIOD_NS, NULL, alloc, true),
    "rcl_timer_init2"))
  {
    return 1;
  }

  rcl_wait_set_t wait_set = rcl_get_zero_initialized_wait_set();
  if (check(rcl_wait_set_init(&wait_set, 3, 0, 1, 0, 0, 0, &context, alloc), "wait set")) {
    return 1;
  }
  rcl_subscription_t * inputs[2] = {&sub_a, &sub_b};
  if (!strcmp(order, "ba")) {
    inputs[0] = &sub_b;
    inputs[1] = &sub_a;
  }
  int have_a = 0, have_b = 0;
  int64_t a = 0, b = 0;
  int code = 0;
  while (!stop && !code && rcl_context_is_valid(&context)) {
    if (check(rcl_wait_set_clear(&wait_set), "rcl_wait_set_clear") ||
      check(rcl_wait_set_add_subscription(&wait_set, &clock_sub, NULL), "add /clock") ||
      check(rcl_wait_set_add_subscription(&wait_set, inputs[0], NULL), "add input") ||
      check(rcl_wait_set_add_subscription(&wait_set, inputs[1], NULL), "add input") ||
      (timer_mode && check(rcl_wait_set_add_timer(&wait_set, &timer, NULL), "add timer")))
    {
      code = 1;
      break;
    }
    rcl_ret_t ret = rcl_wait(&wait_set, RCL_MS_TO_NS(100));
    if (ret == RCL_RET_TIMEOUT) {
      continue;
    }
    if (check(ret, "rcl_wait")) {
      code = 1;
      break;
    }
    for (size_t i = 0; i < wait_set.size_of_subscriptions && !code; ++i) {
      const rcl_subscription_t * sub = wait_set.subscriptions[i];
      if (!sub) {
        continue;
      }
      if (sub == &clock_sub) {
        rosgraph_msgs__msg__Clock msg;
        memset(&msg, 0, sizeof msg);
        if (rcl_take(sub, &msg, NULL, NULL) == RCL_RET_OK) {
          int64_t now = (int64_t)msg.clock.sec * 1000000000LL + msg.clock.nanosec;
          if (check(rcl_set_ros_time_override(&clock, now), "rcl_set_ros_time_override")) {
            stop = 1;
          }
        }
        continue;
      }
      std_msgs__msg__Int64 msg = {0};
      if (rcl_take(sub, &msg, NULL, NULL) != RCL_RET_OK) {
        continue;
      }
      if (sub == &sub_a) {
        a = msg.data;
        have_a = 1;
      } else {
        b = msg.data;
        have_b = 1;
        if (!timer_mode) {
          code = publish(&pub, have_a && have_b, a, b);  /* b's callback publishes */
        }
      }
    }
    if (!code && timer_mode && wait_set.size_of_timers && wait_set.timers[0] &&
      rcl_timer_call(&timer) == RCL_RET_OK)
    {
      code = publish(&pub, have_a && have_b, a, b);
    }
  }
  /* teardown: a failure here changes nothing the run saw */
  int bad = rcl_wait_set_fini(&wait_set) != RCL_RET_OK;
  bad |= rcl_timer_fini(&timer) != RCL_RET_OK;
  bad |= rcl_publisher_fini(&pub, &node) != RCL_RET_OK;
  bad |= rcl_subscription_fini(&sub_b, &node) != RCL_RET_OK;
  bad |= rcl_subscription_fini(&sub_a, &node) != RCL_RET_OK;
  bad |= rcl_subscription_fini(&clock_sub, &node) != RCL_RET_OK;
  bad |= rcl_node_fini(&node) != RCL_RET_OK;
  bad |= rcl_shutdown(&context) != RCL_RET_OK;
  bad |= rcl_context_fini(&context) != RCL_RET_OK;
  bad |= rcl_clock_fini(&clock) != RCL_RET_OK;
  if (bad) {
    fprintf(stderr, "fusion_c: teardown: %s\n", rcl_get_error_string().str);
  }
  return code;
}
